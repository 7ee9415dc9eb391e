#include "server/mapping_service.h"

#include <chrono>
#include <ctime>
#include <optional>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "core/util/version.h"
#include "mapping/gravity.h"
#include "mapping/map_builder.h"
#include "mapping/session_merge.h"
#include "mapstore/map_directory.h"
#include "proto/convert.h"
#include "proto/map_info_convert.h"
#include "proto/mapping_convert.h"
#include "server/log.h"
#include "server/rpc.h"
#include "server/spooled_frames.h"

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

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

uint64_t MappingJobs::Begin(const std::string& map_name, const std::string& robot_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const uint64_t id = next_id_++;
  v1::MappingJob& job = jobs_[id];
  job.set_job_id(id);
  job.set_map_name(map_name);
  job.set_robot_id(robot_id);
  job.set_state(v1::MAPPING_TRACKING);
  job.set_started_unix_ns(UnixNowNs());
  return id;
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
// is taken over by the next stream): its slot, the mapper and what arrived. Ends the job's record
// as FAILED when it is left without an outcome (an exception on the way).
struct ActiveMappingJob {
  // The mapper is made first: a rig it refuses leaves no job behind in the registry.
  ActiveMappingJob(MappingJobs* jobs, std::unique_ptr<JobSlot> slot_in,
                   const v1::MappingStart& start, const proto::StereoRigInput& rig_in,
                   const proto::MappingJobOptions& options_in)
      : registry(jobs),
        slot(std::move(slot_in)),
        rig(rig_in),
        options(options_in),
        builder(rig.left, rig.right, rig.right_from_left, options.builder),
        name(start.map_name()),
        robot_id(start.robot_id()),
        id(jobs->Begin(name, robot_id)) {}
  ~ActiveMappingJob() {
    if (!registry->Ended(id)) registry->End(id, v1::MAPPING_FAILED, "the server failed the job");
  }
  ActiveMappingJob(const ActiveMappingJob&) = delete;
  ActiveMappingJob& operator=(const ActiveMappingJob&) = delete;

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
  // An extension's frames, read again by the merge after MappingEnd.
  std::unique_ptr<SpooledFrames> spool =
      options.extend ? std::make_unique<SpooledFrames>(robot_id.empty() ? name : robot_id, rig)
                     : nullptr;
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

// A frame through the mapper, answered with the build's progress; a bad frame is answered
// MAPPING_FRAME_ERROR with the reason, and the job goes on.
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
    const auto [left, right] = DecodePair(frame, job->rig);
    job->builder.AddFrame(frame.timestamp_ns(), left, right);
    if (job->spool) job->spool->Add(frame, left, right);
    job->last_timestamp_ns = frame.timestamp_ns();
    proto::ToProto(job->builder.Progress(), &progress);
    ShareMapSoFar(job, static_cast<int>(progress.keyframes()));
  } catch (const InputError& e) {
    progress.set_state(v1::MAPPING_FRAME_ERROR);
    progress.set_error(e.what());
  }
  progress.set_frame_index(job->frames++);
  progress.set_timestamp_ns(frame.timestamp_ns());
  progress.set_frame_ms(timer.ElapsedMs());
  progress.set_job_id(job->id);
  job->registry->Update(job->id, progress);
  return progress;
}

// The job's last answer when nothing is published: FAILED with the reason, and the same reason
// as the call's status.
Status Fail(Stream* stream, Job* job, StatusCode code, const std::string& reason) {
  v1::MappingProgress failed;
  failed.set_state(v1::MAPPING_FAILED);
  failed.set_error(reason);
  failed.set_job_id(job->id);
  stream->Write(failed);
  job->registry->End(job->id, v1::MAPPING_FAILED, reason);
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

// After MappingEnd: global adjustment, learning, and the map published under its name.
Status FinishAndPublish(mapstore::MapDirectory folder, const std::string& peer, Stream* stream,
                        Job* job) {
  job->registry->SetState(job->id, v1::MAPPING_FINISHING);
  v1::MappingProgress answer;
  answer.set_state(v1::MAPPING_FINISHING);
  answer.set_frame_index(job->frames);
  answer.set_job_id(job->id);
  stream->Write(answer);
  const int mapped = job->builder.Progress().frames;
  if (mapped == 0) {
    return Fail(stream, job, StatusCode::FAILED_PRECONDITION,
                "no frame was mapped: nothing was published");
  }
  const Timer timer;
  const MapMetadata metadata{
      job->name, static_cast<int64_t>(std::time(nullptr)),
      StrCat("robot ", job->robot_id.empty() ? peer : job->robot_id, " over the link"),
      StrCat("visloc ", VislocVersion(), " mapping service"), ""};
  Map map = job->spool ? Extend(folder, job) : job->builder.Finish(metadata);
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
  job->registry->End(job->id, v1::MAPPING_PUBLISHED, "");
  Log("map_built_over_link", {{"map", job->name},
                              {"frames", std::to_string(job->frames)},
                              {"keyframes", std::to_string(map.keyframes.size())},
                              {"points", std::to_string(map.points.size())},
                              {"finish_ms", StrCat(timer.ElapsedMs())}});
  stream->Write(answer);
  return Status::OK;
}

}  // namespace

MappingService::MappingService(MapCache* maps, const MappingLimits& limits, const TokenAuth* auth)
    : maps_(maps), limits_(limits), auth_(auth) {}

MappingService::~MappingService() = default;

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
    std::unique_ptr<Job> job;
    {
      std::lock_guard<std::mutex> lock(waiting_mutex_);
      const auto found = waiting_.find(start.resume_job_id());
      if (found != waiting_.end() && found->second.job->name == start.map_name()) {
        job = std::move(found->second.job);
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
  auto slot = std::make_unique<JobSlot>(&active_jobs_, limits_.max_jobs);
  if (!slot->held()) {
    *refused = Status(StatusCode::RESOURCE_EXHAUSTED,
                      StrCat(limits_.max_jobs, " mapping job", limits_.max_jobs == 1 ? "" : "s",
                             " already running or waiting to be resumed (--max-mapping-jobs); "
                             "try again when it ends"));
    return nullptr;
  }
  options.builder.threads = limits_.threads;
  auto job = std::make_unique<Job>(&jobs_, std::move(slot), start, rig, options);
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
    jobs_.End(job->id, v1::MAPPING_ABANDONED, broke + ": nothing was published");
    Log("mapping_abandoned",
        {{"map", job->name}, {"frames", std::to_string(job->frames)}, {"reason", why}});
    return Status(StatusCode::ABORTED, broke + ": nothing was published");
  }
  const uint64_t id = job->id;
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
    jobs_.End(job->id, v1::MAPPING_ABANDONED, reason);
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
