#pragma once
// A mapping job's frames kept on disk as they arrived (their encoded bytes, in a temporary
// folder removed with the spool), so that a job that extends a map can read them again after
// MappingEnd: mapping::MergeSession localizes the left images in the map, then maps the pairs.

#include <string>
#include <vector>

#include "core/util/temp_dir.h"
#include "mapping/stereo_source.h"
#include "proto/mapping_convert.h"

namespace visloc::server {

class SpooledFrames final : public mapping::StereoSource {
 public:
  SpooledFrames(std::string name, const proto::StereoRigInput& rig);

  // Keeps one frame that decoded fine: each image's bytes as they arrived (PNG or JPEG; read
  // back they decode to what was mapped), or a raw one as PNG.
  void Add(const v1::StereoFrame& frame, const cv::Mat& left, const cv::Mat& right);

  std::string name() const override { return name_; }
  const Camera& left_camera() const override { return rig_.left; }
  const Camera& right_camera() const override { return rig_.right; }
  Rigid3d right_from_left() const override { return rig_.right_from_left; }
  int size() const override { return static_cast<int>(timestamps_ns_.size()); }
  int64_t TimestampNs(int index) const override { return timestamps_ns_[index]; }
  mapping::StereoImages Read(int index) const override;

 private:
  std::string Path(int index, const char* side) const;
  void Keep(const std::string& encoded, const cv::Mat& decoded, const std::string& path) const;

  std::string name_;
  proto::StereoRigInput rig_;
  TempDir folder_{"visloc-mapping-spool"};
  std::vector<int64_t> timestamps_ns_;
};

}  // namespace visloc::server
