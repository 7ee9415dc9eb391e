#include "dataset/tum.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc {
namespace {

TEST(TumTest, RoundTripKeepsNanosecondTimestamps) {
  TempDir dir;
  const Trajectory trajectory = {
      {1403636579763555584LL,
       Rigid3d(RotationFromRollPitchYaw(0.1, 0.2, 0.3), Eigen::Vector3d(1, 2, 3))},
      {1403636579813555456LL,
       Rigid3d(RotationFromRollPitchYaw(-0.1, 0.0, 2.9), Eigen::Vector3d(-1, 0.5, 0))},
  };
  WriteTum(dir.File("t.tum"), trajectory);
  const Trajectory back = ReadTum(dir.File("t.tum"));
  ASSERT_EQ(back.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back[i].timestamp_ns, trajectory[i].timestamp_ns);
    EXPECT_TRUE(ApproxEqual(back[i].pose, trajectory[i].pose, 1e-9, 1e-6));
  }
}

TEST(TumTest, ParsesSecondsExactly) {
  EXPECT_EQ(*ParseSecondsToNs("1.5"), 1'500'000'000);
  EXPECT_EQ(*ParseSecondsToNs("0.000000001"), 1);
  EXPECT_EQ(*ParseSecondsToNs("12"), 12'000'000'000);
  EXPECT_EQ(*ParseSecondsToNs("1e-3"), 1'000'000);
  EXPECT_FALSE(ParseSecondsToNs("1.2.3"));
  // Beyond what int64 nanoseconds hold (found by the dataset fuzzer: undefined behaviour).
  EXPECT_FALSE(ParseSecondsToNs("1e22"));
  EXPECT_FALSE(ParseSecondsToNs("99999999999.5"));
  EXPECT_FALSE(ParseSecondsToNs("nan"));
  EXPECT_FALSE(ParseSecondsToNs("-inf"));
  EXPECT_EQ(FormatNsAsSeconds(1'500'000'001), "1.500000001");
}

TEST(TumTest, MalformedLinesAreNamed) {
  TempDir dir;
  const std::string path = dir.File("bad.tum");
  std::ofstream(path) << "# comment\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0\n";
  EXPECT_THAT([&] { ReadTum(path); },
              ::testing::ThrowsMessage<InputError>(
                  path + ":3: expected 8 fields (timestamp tx ty tz qx qy qz qw), found 7"));
  std::ofstream(path, std::ios::trunc) << "1.0 0 0 0 0 0 0 2\n";
  EXPECT_THAT([&] { ReadTum(path); }, ::testing::ThrowsMessage<InputError>(
                                          ::testing::HasSubstr(":1: quaternion is not unit")));
  std::ofstream(path, std::ios::trunc) << "2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n";
  EXPECT_THAT([&] { ReadTum(path); },
              ::testing::ThrowsMessage<InputError>(path + ":2: timestamps must increase"));
}

}  // namespace
}  // namespace visloc
