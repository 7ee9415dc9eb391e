#include "server/mapping_service.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <ctime>
#include <filesystem>
#include <optional>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "core/util/timer.h"
#include "core/util/version.h"
#include "mapping/gravity.h"
#include "mapping/map_builder.h"
#include "mapping/session_merge.h"
#include "mapstore/map_directory.h"
#include "proto/convert.h"
#include "proto/map_info_convert.h"
#include "proto/mapping_convert.h"
#include "server/job_spool.h"
#include "server/log.h"
#include "server/rpc.h"

namespace visloc::server {

using grpc::Status;
using grpc::StatusCode;

namespace {

using Stream = grpc::ServerReaderWriter<v1::MappingProgress, v1::MappingRequest>;

// One stereo frame decoded to the rig's cameras, or InputError naming the side and the problem.
std::pair<cv::Mat, cv::Mat> DecodePair(const v1::StereoFrame& frame,
                                       const proto::StereoRigInput& rig) {
  const auto decode = [](const std::string& encoded, const v1::RawImage* raw, const Camera& camera,
                         const char* side) {
    try {
      return proto::DecodeImage(encoded, raw, camera);
    } catch (const InputError& e) {
      throw InputError(StrCat(side, " ", e.what()));
    }
  };
  return {decode(frame.left_encoded(), frame.has_left_raw() ? &frame.left_raw() : nullptr, rig.left,
                 "left"),
          decode(frame.right_encoded(), frame.has_right_raw() ? &frame.right_raw() : nullptr,
                 rig.right, "right")};
}

// Bytes the spool's disk has free for this process, or -1 when it cannot tell.
int64_t FreeDiskBytes(const std::string& dir) {
  struct statvfs disk {};
  if (statvfs(dir.c_str(), &disk) != 0) return -1;
  return static_cast<int64_t>(disk.f_bavail) * static_cast<int64_t>(disk.f_frsize);
}

// Why the spool's disk cannot take more, or empty while it can.
std::string DiskFull(const std::string& dir, int64_t min_free_bytes) {
  const int64_t free_bytes = FreeDiskBytes(dir);
  if (free_bytes < 0 || free_bytes >= min_free_bytes) return "";
  return StrCat("the mapping spool's disk (", dir, ") has ", free_bytes >> 20,
                " MiB free, below its reserve of ", min_free_bytes >> 20,
                " MiB (--mapping-min-free-mib)");
}

std::string UnixTimeText(int64_t unix_ns) {
  const std::time_t seconds = unix_ns / 1'000'000'000;
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&seconds));
  return text;
}

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

uint64_t MappingJobs::Begin(const std::string& map_name, const std::string& robot_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const uint64_t id = next_id_++;
  NewRecord(id, map_name, robot_id, v1::MAPPING_TRACKING);
  return id;
}

void MappingJobs::Adopt(uint64_t id, const std::string& map_name, const std::string& robot_id,
                        const std::string& note) {
  std::lock_guard<std::mutex> lock(mutex_);
  next_id_ = std::max(next_id_, id + 1);
  NewRecord(id, map_name, robot_id, v1::MAPPING_WAITING).set_note(note);
}

v1::MappingJob& MappingJobs::NewRecord(uint64_t id, const std::string& map_name,
                                       const std::string& robot_id, v1::MappingState state) {
  v1::MappingJob& job = jobs_[id];
  job.set_job_id(id);
  job.set_map_name(map_name);
  job.set_robot_id(robot_id);
  job.set_state(state);
  job.set_started_unix_ns(UnixNowNs());
  return job;
}

void MappingJobs::IdsAfter(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  next_id_ = std::max(next_id_, id + 1);
}

void MappingJobs::SetNote(uint64_t id, const std::string& note) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto found = jobs_.find(id); found != jobs_.end()) found->second.set_note(note);
}

void MappingJobs::Update(uint64_t id, const v1::MappingProgress& progress) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = jobs_.find(id);
  if (found == jobs_.end()) return;
  v1::MappingJob& job = found->second;
  job.set_state(progress.state());
  // A frame's answer carries its index; the job's final answer carries the count of frames.
  const bool frame = progress.state() == v1::MAPPING_TRACKING ||
                     progress.state() == v1::MAPPING_LOST ||
                     progress.state() == v1::MAPPING_FRAME_ERROR;
  job.set_frames(frame ? progress.frame_index() + 1 : progress.frame_index());
  if (progress.state() == v1::MAPPING_FRAME_ERROR) return;
  job.set_keyframes(progress.keyframes());
  job.set_points(progress.points());
  job.set_tracking_failures(progress.tracking_failures());
  job.set_has_pose(progress.has_pose());
  if (progress.has_pose()) *job.mutable_map_from_cam() = progress.map_from_cam();
}

void MappingJobs::SetState(uint64_t id, v1::MappingState state) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto found = jobs_.find(id); found != jobs_.end()) found->second.set_state(state);
}

void MappingJobs::End(uint64_t id, v1::MappingState state, const std::string& error) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = jobs_.find(id);
  if (found == jobs_.end()) return;
  found->second.set_state(state);
  found->second.set_error(error);
  found->second.set_ended_unix_ns(UnixNowNs());
  size_t ended = 0;
  for (auto it = jobs_.rbegin(); it != jobs_.rend(); ++it) ended += it->second.ended_unix_ns() != 0;
  for (auto it = jobs_.begin(); ended > keep_ended_ && it != jobs_.end();) {
    if (it->second.ended_unix_ns() != 0) {
      top_views_.erase(it->first);
      it = jobs_.erase(it);
      --ended;
    } else {
      ++it;
    }
  }
}

bool MappingJobs::Ended(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = jobs_.find(id);
  return found == jobs_.end() || found->second.ended_unix_ns() != 0;
}

void MappingJobs::SetMapSoFar(uint64_t id, std::vector<std::pair<float, float>> keyframes_xz,
                              std::vector<std::pair<float, float>> points_xz) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!jobs_.count(id)) return;
  top_views_[id] = {std::move(keyframes_xz), std::move(points_xz)};
}

std::vector<MappingJobView> MappingJobs::Views() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<MappingJobView> views;
  for (const auto& [id, job] : jobs_) {
    MappingJobView view;
    view.id = id;
    view.map = job.map_name();
    view.robot_id = job.robot_id();
    view.state = proto::MappingStateText(job.state());
    view.running = job.ended_unix_ns() == 0;
    view.frames = job.frames();
    view.keyframes = job.keyframes();
    view.points = static_cast<int64_t>(job.points());
    view.has_pose = view.running && job.has_pose();
    if (view.has_pose) view.map_from_cam = proto::FromProto(job.map_from_cam(), "map_from_cam");
    if (const auto found = top_views_.find(id); found != top_views_.end()) {
      view.keyframes_xz = found->second.keyframes_xz;
      view.points_xz = found->second.points_xz;
    }
    views.push_back(std::move(view));
  }
  return views;
}

std::vector<v1::MappingJob> MappingJobs::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<v1::MappingJob> jobs;
  for (const auto& [id, job] : jobs_) jobs.push_back(job);
  return jobs;
}

// One of `limit` job slots, held while it lives; empty when all are taken.
class JobSlot {
 public:
  JobSlot(std::atomic<int>* active, int limit) : active_(active) {
    int now = active_->load();
    while (now < limit && !active_->compare_exchange_weak(now, now + 1)) {
    }
    held_ = now < limit;
  }
  ~JobSlot() {
    if (held_) --*active_;
  }
  JobSlot(const JobSlot&) = delete;
  JobSlot& operator=(const JobSlot&) = delete;
  bool held() const { return held_; }

 private:
  std::atomic<int>* active_;
  bool held_ = false;
};

// One job from its MappingStart to its outcome, across the streams that feed it (a resumed job
// is taken over by the next stream) and the servers that run it (a restarted one takes it up from
// its spool): its slot, the mapper and what arrived. Its outcome removes its spool. A job left
// without an outcome (an exception on the way) is ended FAILED, unless it is parked for its
// robot: a server that stops with a parked job leaves it to the next one.
struct ActiveMappingJob {
  ActiveMappingJob(MappingJobs* jobs, std::unique_ptr<JobSlot> slot_in,
                   const v1::MappingStart& start, const proto::StereoRigInput& rig_in,
                   const proto::MappingJobOptions& options_in, uint64_t id_in)
      : registry(jobs),
        slot(std::move(slot_in)),
        rig(rig_in),
        options(options_in),
        builder(rig.left, rig.right, rig.right_from_left, options.builder),
        name(start.map_name()),
        robot_id(start.robot_id()),
        id(id_in) {}
  ~ActiveMappingJob() {
    if (!registry->Ended(id) && !parked) End(v1::MAPPING_FAILED, "the server failed the job");
  }
  ActiveMappingJob(const ActiveMappingJob&) = delete;
  ActiveMappingJob& operator=(const ActiveMappingJob&) = delete;

  // The job's outcome (PUBLISHED, FAILED or ABANDONED): recorded, and its spool removed.
  void End(v1::MappingState state, const std::string& error) {
    registry->End(id, state, error);
    if (spool) spool->Remove();
  }

  MappingJobs* registry;
  std::unique_ptr<JobSlot> slot;
  proto::StereoRigInput rig;
  proto::MappingJobOptions options;
  mapping::MapBuilder builder;
  std::string name;
  std::string robot_id;
  uint64_t id;
  uint64_t frames = 0;  // Arrived.
  int64_t last_timestamp_ns = 0;
  int shared_keyframes = -1;  // Keyframes when the map so far was last shared.
  bool parked = false;        // Waiting for its robot to resume it.
  // Its start and frames on disk; an extension's merge reads the frames again after MappingEnd.
  std::unique_ptr<JobSpool> spool;
};

namespace {

using Job = ActiveMappingJob;

// The job's map so far for the operator's page: when a keyframe was added, and every 10 frames
// (adjustment moves the rest).
void ShareMapSoFar(Job* job, int keyframes) {
  if (keyframes == job->shared_keyframes && job->frames % 10 != 0) return;
  job->shared_keyframes = keyframes;
  constexpr size_t kMaxPoints = 4000;
  const mapping::MapSoFar view = job->builder.MapSoFarView(kMaxPoints);
  std::vector<std::pair<float, float>> keyframes_xz, points_xz;
  for (const Eigen::Vector3d& c : view.keyframe_centres) keyframes_xz.emplace_back(c.x(), c.z());
  for (const Eigen::Vector3d& p : view.points) points_xz.emplace_back(p.x(), p.z());
  job->registry->SetMapSoFar(job->id, std::move(keyframes_xz), std::move(points_xz));
}

// A frame that is in the spool through the mapper (as it arrives, and again after a restart).
void MapKeptFrame(int64_t timestamp_ns, const cv::Mat& left, const cv::Mat& right, Job* job,
                  v1::MappingProgress* progress) {
  job->builder.AddFrame(timestamp_ns, left, right);
  job->last_timestamp_ns = timestamp_ns;
  proto::ToProto(job->builder.Progress(), progress);
  ShareMapSoFar(job, static_cast<int>(progress->keyframes()));
}

// The job's record after a frame, with the frame's index and time.
void Record(int64_t timestamp_ns, const Timer& timer, Job* job, v1::MappingProgress* progress) {
  progress->set_frame_index(job->frames++);
  progress->set_timestamp_ns(timestamp_ns);
  progress->set_frame_ms(timer.ElapsedMs());
  progress->set_job_id(job->id);
  job->registry->Update(job->id, *progress);
}

// A frame through the mapper, answered with the build's progress; a bad frame is answered
// MAPPING_FRAME_ERROR with the reason, and the job goes on. The frame is in the spool before it
// is mapped, and so before it is answered: a frame answered is never lost with the server.
v1::MappingProgress MapFrame(const v1::StereoFrame& frame, const MappingLimits& limits, Job* job) {
  const Timer timer;
  v1::MappingProgress progress;
  try {
    if (job->frames >= static_cast<uint64_t>(limits.max_frames)) {
      throw InputError(StrCat("the job has its ", limits.max_frames,
                              " frames (--max-mapping-frames); end the stream to publish"));
    }
    if (job->builder.MemoryBytes() > limits.max_memory_bytes) {
      throw InputError(StrCat("the job holds ", job->builder.MemoryBytes() >> 20,
                              " MiB of features and points, its bound (--max-mapping-memory-mib ",
                              limits.max_memory_bytes >> 20, "); end the stream to publish"));
    }
    if (job->builder.stats().frames > 0 && frame.timestamp_ns() <= job->last_timestamp_ns) {
      throw InputError(StrCat("timestamp ", frame.timestamp_ns(), " ns is not after the last ",
                              job->last_timestamp_ns, " ns"));
    }
    if (const std::string full = DiskFull(job->spool->dir(), limits.min_free_disk_bytes);
        !full.empty()) {
      throw InputError(full + "; end the stream to publish");
    }
    const auto [left, right] = DecodePair(frame, job->rig);
    job->spool->Add(frame, left, right);
    MapKeptFrame(frame.timestamp_ns(), left, right, job, &progress);
  } catch (const InputError& e) {
    progress.set_state(v1::MAPPING_FRAME_ERROR);
    progress.set_error(e.what());
  }
  Record(frame.timestamp_ns(), timer, job, &progress);
  return progress;
}

// An answer to the job's stream; a job recovered after a restart has none.
void Answer(Stream* stream, const v1::MappingProgress& answer) {
  if (stream) stream->Write(answer);
}

// The job's last answer when nothing is published: FAILED with the reason, and the same reason
// as the call's status.
Status Fail(Stream* stream, Job* job, StatusCode code, const std::string& reason) {
  v1::MappingProgress failed;
  failed.set_state(v1::MAPPING_FAILED);
  failed.set_error(reason);
  failed.set_job_id(job->id);
  Answer(stream, failed);
  job->End(v1::MAPPING_FAILED, reason);
  Log("mapping_failed", {{"map", job->name}, {"reason", reason}});
  return Status(code, reason);
}

// An extension after MappingEnd: the run merged into the existing map as a new session, as
// `visloc map extend` does (mapping::MergeSession: the run's images localized in the map, the
// run mapped, placed and merged). Throws InputError when the run does not overlap the map.
Map Extend(const mapstore::MapDirectory& folder, Job* job) {
  const Map existing = mapstore::LoadMap(folder.PathOf(job->name));
  mapping::SessionMergeOptions options;
  options.threads = job->options.builder.threads;
  mapping::SessionMergeStats stats;
  return mapping::MergeSession(existing, *job->spool, mapping::SessionMergeKind::kExtend, options,
                               &stats);
}

// How a published map names its job, so that a server restarted between the publication and
// the removal of the job's spool sees that it was published.
std::string PublishedBy(uint64_t job_id) { return StrCat(" (mapping job ", job_id, ")"); }

// Whether the job's map was published before its server stopped.
bool PublishedBefore(const mapstore::MapDirectory& folder, const Job& job) {
  if (!folder.Contains(job.name)) return false;
  const mapstore::MapDirectory::Entry entry = folder.Describe(job.name);
  return entry.info && EndsWith(entry.info->metadata.source_dataset, PublishedBy(job.id));
}

// After MappingEnd: global adjustment, learning, and the map published under its name. `stream`
// is null for a job a restarted server finishes by itself.
Status FinishAndPublish(mapstore::MapDirectory folder, const std::string& peer, Stream* stream,
                        Job* job) {
  job->registry->SetState(job->id, v1::MAPPING_FINISHING);
  Log("mapping_finishing", {{"map", job->name},
                            {"job", std::to_string(job->id)},
                            {"frames", std::to_string(job->frames)}});
  v1::MappingProgress answer;
  answer.set_state(v1::MAPPING_FINISHING);
  answer.set_frame_index(job->frames);
  answer.set_job_id(job->id);
  Answer(stream, answer);
  const int mapped = job->builder.Progress().frames;
  if (mapped == 0) {
    return Fail(stream, job, StatusCode::FAILED_PRECONDITION,
                "no frame was mapped: nothing was published");
  }
  const Timer timer;
  const MapMetadata metadata{job->name, static_cast<int64_t>(std::time(nullptr)),
                             StrCat("robot ", job->robot_id.empty() ? peer : job->robot_id,
                                    " over the link", PublishedBy(job->id)),
                             StrCat("visloc ", VislocVersion(), " mapping service"), ""};
  Map map = job->options.extend ? Extend(folder, job) : job->builder.Finish(metadata);
  // Up, from the floor beneath the keyframes (frames over the link carry no accelerometer).
  if (!map.metadata.gravity) map.metadata.gravity = mapping::GravityFromFloor(map).gravity;
  if (static_cast<int>(map.points.size()) < job->options.min_points) {
    return Fail(stream, job, StatusCode::FAILED_PRECONDITION,
                StrCat("the map would have ", map.points.size(), " points, fewer than ",
                       job->options.min_points, " (min_points) from ", mapped,
                       " frames: nothing was published"));
  }
  const std::string staged = folder.StagingPathFor(job->name);
  mapstore::SaveMap(map, staged);
  answer.Clear();
  proto::ToProto(folder.Publish(staged, job->name, job->options.replace), answer.mutable_map());
  answer.set_state(v1::MAPPING_PUBLISHED);
  answer.set_frame_index(job->frames);
  answer.set_job_id(job->id);
  answer.set_keyframes(static_cast<uint32_t>(map.keyframes.size()));
  answer.set_points(map.points.size());
  answer.set_tracking_failures(static_cast<uint32_t>(job->builder.stats().tracking_failures));
  answer.set_loop_closures(static_cast<uint32_t>(job->builder.stats().loop_closures));
  proto::ToProto(job->builder.stats().disparity_correction, answer.mutable_disparity_correction());
  answer.set_frame_ms(timer.ElapsedMs());
  job->registry->Update(job->id, answer);
  Log("map_built_over_link", {{"map", job->name},
                              {"frames", std::to_string(job->frames)},
                              {"keyframes", std::to_string(map.keyframes.size())},
                              {"points", std::to_string(map.points.size())},
                              {"finish_ms", StrCat(timer.ElapsedMs())}});
  // Answered before the spool goes: a server that dies between the two takes the job up again
  // and finds its map published (PublishedBefore).
  Answer(stream, answer);
  job->End(v1::MAPPING_PUBLISHED, "");
  return Status::OK;
}

}  // namespace

MappingService::MappingService(MapCache* maps, const MappingLimits& limits, const TokenAuth* auth)
    : maps_(maps), limits_(limits), auth_(auth) {
  if (limits_.read_only || limits_.max_jobs == 0) return;  // No job runs here, none is taken up.
  if (limits_.spool_dir.empty()) {
    temporary_spool_ = std::make_unique<TempDir>("visloc-mapping-spool");
    limits_.spool_dir = temporary_spool_->path();
  }
  // A spool that exists may hold jobs to take up; one that does not is made by the first job.
  if (!std::filesystem::exists(limits_.spool_dir)) return;
  if (HoldSpool()) {
    Recover();
  } else {
    Log("mapping_spool_held", {{"spool", limits_.spool_dir},
                               {"reason", "another server holds it: its jobs are that one's"}});
  }
}

MappingService::~MappingService() {
  stopping_ = true;
  if (recovery_.joinable()) recovery_.join();
  if (spool_lock_fd_ >= 0) close(spool_lock_fd_);
}

bool MappingService::HoldSpool() {
  std::lock_guard<std::mutex> lock(spool_mutex_);
  if (spool_lock_fd_ >= 0) return true;
  std::error_code ignored;  // A folder that cannot be made fails the open below.
  std::filesystem::create_directories(limits_.spool_dir, ignored);
  const int fd = open((limits_.spool_dir + "/lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return false;
  if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
    close(fd);
    return false;
  }
  spool_lock_fd_ = fd;
  return true;
}

uint64_t MappingService::NextJobId(const std::string& map_name, const std::string& robot_id) {
  const uint64_t id = jobs_.Begin(map_name, robot_id);
  // The next server hands out ids after this one, though its spool may be empty by then: a
  // robot resuming a job of the last server must never reach another job of the same id.
  WriteFileAtomically(limits_.spool_dir + "/next_id", StrCat(id + 1, "\n"));
  return id;
}

void MappingService::Recover() {
  const std::string next_id_path = limits_.spool_dir + "/next_id";
  const std::vector<uint64_t> ids = JobSpool::JobIds(limits_.spool_dir);
  uint64_t last_id = ids.empty() ? 0 : ids.back();
  if (std::filesystem::exists(next_id_path)) {
    try {
      last_id = std::max<uint64_t>(last_id, std::stoull(ReadFileBytes(next_id_path)) - 1);
    } catch (const std::exception&) {  // A torn or foreign file: the folders' ids serve.
    }
  }
  jobs_.IdsAfter(last_id);
  const std::string restarted = UnixTimeText(UnixNowNs());
  for (const uint64_t id : ids) {
    const std::string dir = StrCat(limits_.spool_dir, "/", id);
    std::unique_ptr<JobSpool> spool;
    try {
      spool = JobSpool::Open(dir, limits_.wire);
      proto::MappingJobOptions options = proto::FromProto(spool->start().options());
      options.builder.threads = limits_.threads;
      // Recovered jobs hold slots beyond the limit: they were admitted by the last server.
      auto slot = std::make_unique<JobSlot>(&active_jobs_, INT_MAX);
      auto job =
          std::make_unique<Job>(&jobs_, std::move(slot), spool->start(), spool->rig(), options, id);
      jobs_.Adopt(id, job->name, job->robot_id,
                  StrCat("its server stopped after ", spool->size(), " frames",
                         spool->ended() ? ", after MappingEnd" : "", "; the server started at ",
                         restarted, " took it up from its spool and maps its frames again"));
      job->spool = std::move(spool);
      recovering_.insert(id);
      to_recover_.push_back(std::move(job));
    } catch (const std::exception& e) {
      // A spool that cannot be taken up is recorded and dropped: it would fail every restart.
      jobs_.Adopt(
          id, "", "",
          "its server stopped; the server started at " + restarted + " found its spool unusable");
      jobs_.End(id, v1::MAPPING_FAILED, e.what());
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
      Log("mapping_spool_unusable", {{"job", std::to_string(id)}, {"reason", e.what()}});
    }
  }
  if (to_recover_.empty()) return;
  recovery_ = std::thread([this] {
    for (std::unique_ptr<Job>& job : to_recover_) {
      const uint64_t id = job->id;
      try {
        Replay(std::move(job));
      } catch (const std::exception& e) {  // The job's destructor has ended it FAILED.
        Log("mapping_recovery_failed", {{"job", std::to_string(id)}, {"reason", e.what()}});
      }
      std::lock_guard<std::mutex> lock(recovery_mutex_);
      recovering_.erase(id);
      recovered_.notify_all();
    }
  });
}

void MappingService::Replay(std::unique_ptr<Job> job) {
  const Timer timer;
  const int kept = job->spool->size();
  Log("mapping_recovering", {{"map", job->name},
                             {"job", std::to_string(job->id)},
                             {"frames", std::to_string(kept)},
                             {"ended", job->spool->ended() ? "true" : "false"}});
  for (int i = 0; i < kept; ++i) {
    if (stopping_) {
      job->parked = true;  // This server stops too: the spool stays for the next one.
      return;
    }
    const Timer frame_timer;
    mapping::StereoImages images;
    try {
      images = job->spool->Read(i);
    } catch (const InputError& e) {  // A disk that lost what it was given.
      job->End(v1::MAPPING_FAILED, StrCat("its server stopped after ", kept,
                                          " frames, and they cannot be mapped again: ", e.what(),
                                          ": nothing was published"));
      return;
    }
    v1::MappingProgress progress;
    try {
      MapKeptFrame(images.timestamp_ns, images.left_raw, images.right_raw, job.get(), &progress);
    } catch (const InputError& e) {  // As the frame was answered when it arrived.
      progress.set_state(v1::MAPPING_FRAME_ERROR);
      progress.set_error(e.what());
    }
    Record(images.timestamp_ns, frame_timer, job.get(), &progress);
  }
  Log("mapping_recovered", {{"map", job->name},
                            {"job", std::to_string(job->id)},
                            {"frames", std::to_string(kept)},
                            {"ms", StrCat(timer.ElapsedMs())}});
  if (!job->spool->ended()) {
    Park(std::move(job), "its server stopped");
    return;
  }
  // The robot asked for the map before the server stopped: it is finished without the robot.
  if (PublishedBefore(maps_->directory(), *job)) {
    job->End(v1::MAPPING_PUBLISHED, "");
    return;
  }
  try {
    FinishAndPublish(maps_->directory(), "", nullptr, job.get());
  } catch (const std::exception& e) {
    job->End(v1::MAPPING_FAILED, StrCat(e.what(), ": nothing was published"));
  }
}

void MappingService::AwaitRecovery(uint64_t job_id) {
  std::unique_lock<std::mutex> lock(recovery_mutex_);
  recovered_.wait(lock, [&] { return !recovering_.count(job_id); });
}

Status MappingService::Refuse(const v1::MappingStart& start, bool replace) const {
  if (limits_.read_only) {
    return Status(StatusCode::FAILED_PRECONDITION,
                  "this server's maps folder is read-only (--maps-read-only): build maps on the "
                  "fleet's admin server");
  }
  if (limits_.max_jobs == 0) {
    return Status(StatusCode::FAILED_PRECONDITION,
                  "mapping over the link is off on this server (--max-mapping-jobs 0)");
  }
  mapstore::CheckMapName(start.map_name());
  if (const std::string full = DiskFull(limits_.spool_dir, limits_.min_free_disk_bytes);
      !full.empty()) {
    return Status(StatusCode::RESOURCE_EXHAUSTED, full + ": no mapping job can be kept");
  }
  if (start.options().extend() && !maps_->directory().Contains(start.map_name())) {
    return Status(StatusCode::NOT_FOUND, StrCat("no map named '", start.map_name(),
                                                "' to extend; build it first (without extend)"));
  }
  if (maps_->directory().Contains(start.map_name()) && !replace) {
    return Status(StatusCode::ALREADY_EXISTS,
                  StrCat("a map named '", start.map_name(),
                         "' already exists; build with --replace (MappingOptions.replace) to "
                         "replace it when the new one is published"));
  }
  return Status::OK;
}

std::unique_ptr<ActiveMappingJob> MappingService::Open(const grpc::ServerContext& context,
                                                       const v1::MappingStart& start,
                                                       Stream* stream, Status* refused) {
  if (start.resume_job_id() != 0) {
    AwaitRecovery(start.resume_job_id());  // A job this server took up from its spool.
    std::unique_ptr<Job> job;
    {
      std::lock_guard<std::mutex> lock(waiting_mutex_);
      const auto found = waiting_.find(start.resume_job_id());
      if (found != waiting_.end() && found->second.job->name == start.map_name()) {
        job = std::move(found->second.job);
        job->parked = false;
        waiting_.erase(found);
      }
    }
    if (!job) {
      *refused = Status(
          StatusCode::NOT_FOUND,
          StrCat("mapping job ", start.resume_job_id(), " of '", start.map_name(),
                 "' is not waiting to be resumed (it ended, or its ", limits_.resume_window_s,
                 " s window passed): nothing of it was published; build again"));
      return nullptr;
    }
    v1::MappingProgress resumed;
    proto::ToProto(job->builder.Progress(), &resumed);
    resumed.set_state(v1::MAPPING_RESUMED);
    resumed.set_frame_index(job->frames);
    resumed.set_timestamp_ns(job->last_timestamp_ns);
    resumed.set_job_id(job->id);
    jobs_.SetState(job->id, v1::MAPPING_TRACKING);
    Log("mapping_resumed", {{"map", job->name},
                            {"job", std::to_string(job->id)},
                            {"frames", std::to_string(job->frames)},
                            {"peer", context.peer()}});
    stream->Write(resumed);
    return job;
  }
  proto::MappingJobOptions options = proto::FromProto(start.options());
  if (*refused = Refuse(start, options.replace); !refused->ok()) return nullptr;
  const proto::StereoRigInput rig = proto::FromProto(start.rig(), limits_.wire);
  if (!HoldSpool()) {
    *refused = Status(StatusCode::UNAVAILABLE,
                      StrCat("the mapping spool ", limits_.spool_dir,
                             " is held by another visloc-server on the same folder: map there, "
                             "or give this one its own --mapping-spool"));
    return nullptr;
  }
  auto slot = std::make_unique<JobSlot>(&active_jobs_, limits_.max_jobs);
  if (!slot->held()) {
    *refused = Status(StatusCode::RESOURCE_EXHAUSTED,
                      StrCat(limits_.max_jobs, " mapping job", limits_.max_jobs == 1 ? "" : "s",
                             " already running or waiting to be resumed (--max-mapping-jobs); "
                             "try again when it ends"));
    return nullptr;
  }
  options.builder.threads = limits_.threads;
  // The mapper is made first: a rig it refuses leaves no job behind in the registry.
  auto job = std::make_unique<Job>(&jobs_, std::move(slot), start, rig, options, 0);
  job->id = NextJobId(job->name, job->robot_id);
  try {
    job->spool = JobSpool::Create(limits_.spool_dir, job->id, start, limits_.wire);
  } catch (const InputError& e) {
    *refused = Status(StatusCode::UNAVAILABLE, StrCat(e.what(), ": the job cannot be kept"));
    return nullptr;  // The job's destructor ends it FAILED.
  }
  v1::MappingProgress started;
  started.set_state(v1::MAPPING_STARTED);
  started.set_job_id(job->id);
  stream->Write(started);
  Log("mapping_started", {{"map", job->name},
                          {"job", std::to_string(job->id)},
                          {"robot", job->robot_id},
                          {"peer", context.peer()},
                          {"replace", options.replace ? "true" : "false"}});
  return job;
}

Status MappingService::Park(std::unique_ptr<ActiveMappingJob> job, const std::string& why) {
  const std::string broke = StrCat("the mapping stream of '", job->name, "' broke after ",
                                   job->frames, " frames (", why, ")");
  if (limits_.resume_window_s <= 0) {
    job->End(v1::MAPPING_ABANDONED, broke + ": nothing was published");
    Log("mapping_abandoned",
        {{"map", job->name}, {"frames", std::to_string(job->frames)}, {"reason", why}});
    return Status(StatusCode::ABORTED, broke + ": nothing was published");
  }
  const uint64_t id = job->id;
  job->parked = true;
  jobs_.SetState(id, v1::MAPPING_WAITING);
  Log("mapping_waiting", {{"map", job->name},
                          {"job", std::to_string(id)},
                          {"frames", std::to_string(job->frames)},
                          {"reason", why}});
  const std::string message =
      StrCat(broke, ": job ", id, " waits ", limits_.resume_window_s,
             " s to be resumed (MappingStart.resume_job_id); nothing is published until it ends");
  std::lock_guard<std::mutex> lock(waiting_mutex_);
  const auto window = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(limits_.resume_window_s));
  waiting_[id] = {std::chrono::steady_clock::now() + window, std::move(job)};
  return Status(StatusCode::ABORTED, message);
}

void MappingService::ExpireWaitingJobs() {
  std::vector<std::unique_ptr<Job>> expired;
  {
    std::lock_guard<std::mutex> lock(waiting_mutex_);
    const auto now = std::chrono::steady_clock::now();
    for (auto it = waiting_.begin(); it != waiting_.end();) {
      if (it->second.deadline > now) {
        ++it;
        continue;
      }
      expired.push_back(std::move(it->second.job));
      it = waiting_.erase(it);
    }
  }
  for (const std::unique_ptr<Job>& job : expired) {
    const std::string reason = StrCat("the mapping stream of '", job->name, "' broke after ",
                                      job->frames, " frames and was not resumed within ",
                                      limits_.resume_window_s, " s: nothing was published");
    job->End(v1::MAPPING_ABANDONED, reason);
    Log("mapping_abandoned", {{"map", job->name},
                              {"job", std::to_string(job->id)},
                              {"frames", std::to_string(job->frames)},
                              {"reason", "not resumed in time"}});
  }
}

Status MappingService::BuildMap(grpc::ServerContext* context, Stream* stream) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "BuildMap", [&] {
    ExpireWaitingJobs();
    v1::MappingRequest request;
    if (!stream->Read(&request) || !request.has_start()) {
      return Status(StatusCode::INVALID_ARGUMENT, "a mapping stream starts with MappingStart");
    }
    Status refused;
    std::unique_ptr<Job> job = Open(*context, request.start(), stream, &refused);
    if (!job) return refused;
    bool ended = false;
    while (!ended && stream->Read(&request)) {
      if (request.has_end()) {
        ended = true;
      } else if (!request.has_frame()) {
        return Fail(stream, job.get(), StatusCode::INVALID_ARGUMENT,
                    "a mapping stream has one MappingStart, then frames: nothing was published");
      } else if (!stream->Write(MapFrame(request.frame(), limits_, job.get()))) {
        break;
      }
    }
    if (ended) job->spool->MarkEnded();  // A server that stops now finishes it when restarted.
    if (!ended) {
      return Park(std::move(job),
                  context->IsCancelled() ? "the client went away" : "no MappingEnd");
    }
    return FinishAndPublish(maps_->directory(), context->peer(), stream, job.get());
  });
}

Status MappingService::ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest*,
                                v1::ListJobsResponse* response) {
  return HandleRpc(*auth_, *context, Role::kLocalize, "ListJobs", [&] {
    ExpireWaitingJobs();
    for (const v1::MappingJob& job : jobs_.Snapshot()) *response->add_jobs() = job;
    response->set_server_time_unix_ns(UnixNowNs());
    response->set_max_jobs(static_cast<uint32_t>(limits_.max_jobs));
    return Status::OK;
  });
}

}  // namespace visloc::server
