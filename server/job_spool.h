#pragma once
// A mapping job kept on disk as it arrives, so that it outlives its server: a restarted server
// (or the admin replica that replaces it on a shared maps folder) finds the job here, maps its
// frames again and takes it up where the robot resumes it. An extension reads its frames again
// after MappingEnd (mapping::MergeSession).
//
// One folder per job, SPOOL/<job id>/:
//   start.pb       the job's MappingStart (map name, rig, options, robot), written once,
//                  atomically;
//   frames.log     one line "INDEX TIMESTAMP_NS" per frame kept, appended after its images;
//   INDEX_left, INDEX_right   each image's bytes as they arrived (PNG or JPEG), raw ones as PNG;
//   end            written when MappingEnd arrived: the robot asked for the map.
// The log is flushed with every frame (a killed process loses nothing it answered); it is
// synced to the disk at most once a second, so a power cut may lose the last second, which a
// restart detects (a frame whose image is missing or does not decode ends the job's frames).

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "mapping/stereo_source.h"
#include "proto/mapping_convert.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::server {

class JobSpool final : public mapping::StereoSource {
 public:
  // A new job's folder SPOOL/<id>/ with its start. Throws InputError when it cannot be written.
  static std::unique_ptr<JobSpool> Create(const std::string& spool_dir, uint64_t job_id,
                                          const v1::MappingStart& start,
                                          const proto::WireLimits& wire);
  // A job's folder as an earlier server left it. Throws InputError naming the folder and what is
  // wrong (no start, a start that does not parse, an invalid rig); a log torn by the crash loses
  // its unfinished line only.
  static std::unique_ptr<JobSpool> Open(const std::string& job_dir, const proto::WireLimits& wire);
  // The job ids of the folders under `spool_dir`, in order (none when it is missing).
  static std::vector<uint64_t> JobIds(const std::string& spool_dir);

  ~JobSpool() override;
  JobSpool(const JobSpool&) = delete;
  JobSpool& operator=(const JobSpool&) = delete;

  // Keeps one frame that decoded fine: each image's bytes as they arrived (read back they decode
  // to what was mapped), or a raw one as PNG; then its line in the log.
  void Add(const v1::StereoFrame& frame, const cv::Mat& left, const cv::Mat& right);
  void MarkEnded();
  bool ended() const { return ended_; }
  // Deletes the job's folder (the job has its outcome). The spool is unusable afterwards.
  void Remove();

  uint64_t job_id() const { return job_id_; }
  const std::string& dir() const { return dir_; }
  const v1::MappingStart& start() const { return start_; }
  const proto::StereoRigInput& rig() const { return rig_; }

  std::string name() const override;
  const Camera& left_camera() const override { return rig_.left; }
  const Camera& right_camera() const override { return rig_.right; }
  Rigid3d right_from_left() const override { return rig_.right_from_left; }
  int size() const override { return static_cast<int>(timestamps_ns_.size()); }
  int64_t TimestampNs(int index) const override { return timestamps_ns_[index]; }
  // Throws InputError when the frame's images are missing or do not decode.
  mapping::StereoImages Read(int index) const override;

 private:
  JobSpool(std::string dir, uint64_t job_id, v1::MappingStart start, const proto::WireLimits& wire);
  std::string Path(int index, const char* side) const;
  void Keep(const std::string& encoded, const cv::Mat& decoded, const std::string& path) const;
  void OpenLog();
  void ReadLog();

  std::string dir_;
  uint64_t job_id_;
  v1::MappingStart start_;
  proto::StereoRigInput rig_;
  std::vector<int64_t> timestamps_ns_;
  bool ended_ = false;
  FILE* log_ = nullptr;
  int64_t last_sync_ns_ = 0;  // Steady clock.
};

}  // namespace visloc::server
