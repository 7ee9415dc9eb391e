#include "ros/bag/stereo_pairer.h"

#include <gtest/gtest.h>

#include <vector>

namespace visloc::bag {
namespace {

struct Recorder {
  std::vector<int64_t> stamps;
  StereoPairer::EmitFn Fn() {
    return [this](int64_t t, const cv::Mat&, const cv::Mat&) { stamps.push_back(t); };
  }
};

cv::Mat Image() { return cv::Mat(2, 2, CV_8UC1, cv::Scalar(0)); }

TEST(StereoPairerTest, PairsSynchronizedCamerasAsTheyArrive) {
  Recorder out;
  StereoPairer pairer(1'000'000, out.Fn());
  for (int64_t t = 0; t < 5; ++t) {
    pairer.AddLeft(t * 50'000'000, Image());
    pairer.AddRight(t * 50'000'000, Image());
    EXPECT_EQ(out.stamps.size(), static_cast<size_t>(t + 1));  // Streaming, not at the end.
  }
  pairer.Finish();
  EXPECT_EQ(pairer.stats().paired, 5);
  EXPECT_EQ(pairer.stats().unpaired_left + pairer.stats().unpaired_right, 0);
}

TEST(StereoPairerTest, ReportsDroppedImagesAndPairsTheClosest) {
  Recorder out;
  StereoPairer pairer(5'000'000, out.Fn());
  // Right arrives 2 ms late; the right image of 100 ms is missing; an extra right at 152 ms is
  // farther from 150 ms than the one at 151 ms.
  pairer.AddLeft(50'000'000, Image());
  pairer.AddRight(52'000'000, Image());
  pairer.AddLeft(100'000'000, Image());
  pairer.AddLeft(150'000'000, Image());
  pairer.AddRight(151'000'000, Image());
  pairer.AddRight(152'000'000, Image());
  pairer.AddLeft(200'000'000, Image());
  pairer.AddRight(200'000'000, Image());
  pairer.Finish();
  EXPECT_EQ(out.stamps, (std::vector<int64_t>{50'000'000, 150'000'000, 200'000'000}));
  EXPECT_EQ(pairer.stats().unpaired_left, 1);
  EXPECT_EQ(pairer.stats().unpaired_right, 1);
  EXPECT_EQ(pairer.stats().max_offset_ns, 2'000'000);
}

TEST(StereoPairerTest, OrdersInterleavedStampsAndRefusesLateOnes) {
  Recorder out;
  StereoPairer pairer(0, out.Fn());
  pairer.AddLeft(20, Image());
  pairer.AddLeft(10, Image());  // Recorded after 20, stamped before.
  pairer.AddRight(10, Image());
  pairer.AddRight(20, Image());
  pairer.AddLeft(5, Image());   // Older than a written frame.
  pairer.Finish();
  EXPECT_EQ(out.stamps, (std::vector<int64_t>{10, 20}));
  EXPECT_EQ(pairer.stats().out_of_order, 1);
}

TEST(StereoPairerTest, MemoryStaysBoundedWhenOneCameraIsSilent) {
  Recorder out;
  StereoPairer pairer(0, out.Fn());
  for (int64_t t = 0; t < 1000; ++t) pairer.AddLeft(t, Image());
  pairer.Finish();
  EXPECT_TRUE(out.stamps.empty());
  EXPECT_EQ(pairer.stats().unpaired_left, 1000);
}

}  // namespace
}  // namespace visloc::bag
