#include "server/spooled_frames.h"

#include <opencv2/imgcodecs.hpp>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::server {

SpooledFrames::SpooledFrames(std::string name, const proto::StereoRigInput& rig)
    : name_(std::move(name)), rig_(rig) {}

std::string SpooledFrames::Path(int index, const char* side) const {
  return folder_.File(StrCat(index, "_", side, ".png"));
}

void SpooledFrames::Add(int64_t timestamp_ns, const cv::Mat& left, const cv::Mat& right) {
  const int index = size();
  // Fast PNG: the spool is read back once, and disk is cheaper than the server's time.
  const std::vector<int> fast = {cv::IMWRITE_PNG_COMPRESSION, 1};
  if (!cv::imwrite(Path(index, "left"), left, fast) ||
      !cv::imwrite(Path(index, "right"), right, fast)) {
    throw InputError(StrCat("cannot keep frame ", index, " of the run in ", folder_.path()));
  }
  timestamps_ns_.push_back(timestamp_ns);
}

mapping::StereoImages SpooledFrames::Read(int index) const {
  const auto read = [&](const char* side) {
    cv::Mat image = cv::imread(Path(index, side), cv::IMREAD_GRAYSCALE);
    if (image.empty())
      throw InputError(StrCat("frame ", index, " of the run: cannot read it back"));
    return image;
  };
  return {timestamps_ns_[index], read("left"), read("right")};
}

}  // namespace visloc::server
