#include "server/spooled_frames.h"

#include <cstdio>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc::server {

SpooledFrames::SpooledFrames(std::string name, const proto::StereoRigInput& rig)
    : name_(std::move(name)), rig_(rig) {}

std::string SpooledFrames::Path(int index, const char* side) const {
  return folder_.File(StrCat(index, "_", side));  // imread tells PNG from JPEG by content.
}

void SpooledFrames::Keep(const std::string& encoded, const cv::Mat& decoded,
                         const std::string& path) const {
  bool kept = false;
  if (!encoded.empty()) {
    std::ofstream out(path, std::ios::binary);
    kept =
        static_cast<bool>(out.write(encoded.data(), static_cast<std::streamsize>(encoded.size())));
  } else {
    // Fast PNG: the spool is read back once, and disk is cheaper than the server's time.
    kept = cv::imwrite(path + ".png", decoded, {cv::IMWRITE_PNG_COMPRESSION, 1}) &&
           std::rename((path + ".png").c_str(), path.c_str()) == 0;
  }
  if (!kept) throw InputError(StrCat("cannot keep a frame of the run in ", folder_.path()));
}

void SpooledFrames::Add(const v1::StereoFrame& frame, const cv::Mat& left, const cv::Mat& right) {
  const int index = size();
  Keep(frame.left_encoded(), left, Path(index, "left"));
  Keep(frame.right_encoded(), right, Path(index, "right"));
  timestamps_ns_.push_back(frame.timestamp_ns());
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
