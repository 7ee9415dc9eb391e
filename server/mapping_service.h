#pragma once
// The Mapping service: a robot streams a stereo run and the server builds the map with the same
// mapper as `visloc map build` (mapping::MapBuilder), fed frame by frame, answering each frame
// with the build's progress. When the client ends the stream with MappingEnd the server runs
// global bundle adjustment, visibility learning and the vocabulary, writes the map beside the
// maps folder and publishes it under its name with one atomic rename (mapstore::MapDirectory):
// sessions localizing in a replaced map keep it, new sessions get the new one. A stream that
// breaks, or ends without MappingEnd, publishes nothing.
//
// A job outlives its server: its start and frames are kept on disk as they arrive (JobSpool,
// under the maps folder by default, so a replica that takes over a shared folder finds them). A
// restarted server maps the kept frames again, in order, which rebuilds the mapper's state as it
// was (the mapper is deterministic at one thread), then waits for the robot to resume the job;
// a job whose MappingEnd had arrived is finished and published without it.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/util/temp_dir.h"
#include "proto/geometry_convert.h"
#include "server/auth.h"
#include "server/map_cache.h"
#include "server/server_status.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

struct ActiveMappingJob;  // One job's mapper and state (mapping_service.cc).

struct MappingLimits {
  // Jobs at once; more are refused (RESOURCE_EXHAUSTED). A job holds its frames' features and
  // the map so far in memory, and takes a core while frames arrive.
  int max_jobs = 1;
  int threads = 1;  // Each job's threads (mapping::MapBuilderOptions::threads).
  // Frames one job takes, and the memory its mapper may hold (MapBuilder::MemoryBytes); frames
  // beyond either are answered MAPPING_FRAME_ERROR, and the client may end the run to publish.
  int max_frames = 20000;
  size_t max_memory_bytes = size_t{2048} << 20;
  bool read_only = false;  // A replica of a shared maps folder: mapping is refused.
  // A job whose stream breaks waits this long for its client to resume it
  // (MappingStart.resume_job_id), keeping its map so far and its slot; 0: it is dropped at once.
  double resume_window_s = 30.0;
  proto::WireLimits wire;
  // Where jobs are kept as they arrive (job_spool.h); the server's default is
  // MAPS/.mapping-jobs. Empty: a temporary folder that dies with the service.
  std::string spool_dir;
  // A job is refused, and its frames answered MAPPING_FRAME_ERROR, while the spool's disk has
  // less free space than this.
  int64_t min_free_disk_bytes = int64_t{1} << 30;
};

// The server's mapping jobs, running and recently ended, for ListJobs (`visloc jobs`). Thread-safe.
class MappingJobs {
 public:
  explicit MappingJobs(size_t keep_ended = 32) : keep_ended_(keep_ended) {}
  // A new running job; returns its id.
  uint64_t Begin(const std::string& map_name, const std::string& robot_id);
  // A job an earlier server left in the spool, under its own id (later ids follow it).
  void Adopt(uint64_t id, const std::string& map_name, const std::string& robot_id,
             const std::string& note);
  // New ids start after `id` (the ids a spool has handed out before a restart).
  void IdsAfter(uint64_t id);
  // What happened to the job that its answers do not say (a restart of its server).
  void SetNote(uint64_t id, const std::string& note);
  // A frame's answer: its state, and for a mapped frame the counts and pose.
  void Update(uint64_t id, const v1::MappingProgress& progress);
  void SetState(uint64_t id, v1::MappingState state);
  // Ends a job (PUBLISHED, FAILED or ABANDONED); only the newest keep_ended ended jobs are kept.
  void End(uint64_t id, v1::MappingState state, const std::string& error);
  bool Ended(uint64_t id) const;
  // The job's map so far from above (x, z), for the operator's page.
  void SetMapSoFar(uint64_t id, std::vector<std::pair<float, float>> keyframes_xz,
                   std::vector<std::pair<float, float>> points_xz);
  std::vector<v1::MappingJob> Snapshot() const;
  std::vector<MappingJobView> Views() const;

 private:
  // A job's record from its start (mutex_ held).
  v1::MappingJob& NewRecord(uint64_t id, const std::string& map_name, const std::string& robot_id,
                            v1::MappingState state);

  mutable std::mutex mutex_;
  uint64_t next_id_ = 1;
  std::map<uint64_t, v1::MappingJob> jobs_;
  struct TopView {
    std::vector<std::pair<float, float>> keyframes_xz, points_xz;
  };
  std::map<uint64_t, TopView> top_views_;  // Of the jobs in jobs_.
  size_t keep_ended_;
};

class MappingService final : public v1::Mapping::Service {
 public:
  // Every call needs the admin role. `maps` and `auth` must outlive the service.
  MappingService(MapCache* maps, const MappingLimits& limits, const TokenAuth* auth);
  // Recovers the jobs the spool holds (in a thread of its own: see the file's comment).
  ~MappingService() override;

  grpc::Status BuildMap(
      grpc::ServerContext* context,
      grpc::ServerReaderWriter<v1::MappingProgress, v1::MappingRequest>* stream) override;
  grpc::Status ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest*,
                        v1::ListJobsResponse* response) override;

  // Drops the jobs that waited longer than the resume window (each logged and listed as
  // abandoned). The server's janitor calls it; every call of the service does too.
  void ExpireWaitingJobs();

  int active_jobs() const { return active_jobs_.load(); }
  std::vector<v1::MappingJob> jobs() const { return jobs_.Snapshot(); }
  std::vector<MappingJobView> job_views() const { return jobs_.Views(); }

 private:
  // Why a job may not start (read-only folder, mapping off, a bad name, a name taken without
  // `replace`); OK otherwise.
  grpc::Status Refuse(const v1::MappingStart& start, bool replace) const;
  // A new job for `start`, or the waiting job it resumes (answered MAPPING_RESUMED); null with
  // `refused` set when there is none.
  std::unique_ptr<ActiveMappingJob> Open(
      const grpc::ServerContext& context, const v1::MappingStart& start,
      grpc::ServerReaderWriter<v1::MappingProgress, v1::MappingRequest>* stream,
      grpc::Status* refused);
  // A job whose stream broke: kept for the resume window, or abandoned without one.
  grpc::Status Park(std::unique_ptr<ActiveMappingJob> job, const std::string& why);
  // The spool's jobs taken up again: each one's frames mapped again, then parked for its robot,
  // or finished and published when its MappingEnd had arrived.
  void Recover();
  void Replay(std::unique_ptr<ActiveMappingJob> job);
  // Blocks a resumption of a job being recovered until its frames are mapped again.
  void AwaitRecovery(uint64_t job_id);
  // Whether this server holds the spool (an flock on SPOOL/lock, taken once and kept): two
  // servers must never take up the same jobs. Made when missing.
  bool HoldSpool();
  // A new job in the registry; its id handed out durably (the spool's next_id file).
  uint64_t NextJobId(const std::string& map_name, const std::string& robot_id);

  MapCache* maps_;
  MappingLimits limits_;
  std::unique_ptr<TempDir> temporary_spool_;  // When limits_.spool_dir is empty.
  std::mutex spool_mutex_;
  int spool_lock_fd_ = -1;  // Held while the service lives.
  const TokenAuth* auth_;
  std::atomic<int> active_jobs_{0};
  MappingJobs jobs_;
  struct WaitingJob {
    std::chrono::steady_clock::time_point deadline;
    std::unique_ptr<ActiveMappingJob> job;
  };
  std::mutex waiting_mutex_;
  std::map<uint64_t, WaitingJob> waiting_;  // By job id.
  std::mutex recovery_mutex_;
  std::condition_variable recovered_;
  std::vector<std::unique_ptr<ActiveMappingJob>> to_recover_;  // Replayed in order.
  std::set<uint64_t> recovering_;                              // Their ids, until parked or ended.
  std::atomic<bool> stopping_{false};
  std::thread recovery_;
};

}  // namespace visloc::server
