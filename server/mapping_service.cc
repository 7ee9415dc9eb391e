#include "server/mapping_service.h"

#include <ctime>
#include <optional>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/timer.h"
#include "core/util/version.h"
#include "mapping/map_builder.h"
#include "mapstore/map_directory.h"
#include "proto/convert.h"
#include "proto/map_info_convert.h"
#include "proto/mapping_convert.h"
#include "server/log.h"
#include "server/rpc.h"

namespace visloc::server {

using grpc::Status;
using grpc::StatusCode;

namespace {

using Stream = grpc::ServerReaderWriter<v1::MappingProgress, v1::MappingRequest>;

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

// The job's last answer when nothing is published: FAILED with the reason, and the same reason
// as the call's status.
Status Fail(Stream* stream, const std::string& map_name, StatusCode code,
            const std::string& reason) {
  v1::MappingProgress failed;
  failed.set_state(v1::MAPPING_FAILED);
  failed.set_error(reason);
  stream->Write(failed);
  Log("mapping_failed", {{"map", map_name}, {"reason", reason}});
  return Status(code, reason);
}

}  // namespace

MappingService::MappingService(MapCache* maps, const MappingLimits& limits, const TokenAuth* auth)
    : maps_(maps), limits_(limits), auth_(auth) {}

Status MappingService::BuildMap(grpc::ServerContext* context, Stream* stream) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "BuildMap", [&] {
    if (limits_.read_only) {
      return Status(StatusCode::FAILED_PRECONDITION,
                    "this server's maps folder is read-only (--maps-read-only): build maps on "
                    "the fleet's admin server");
    }
    if (limits_.max_jobs == 0) {
      return Status(StatusCode::FAILED_PRECONDITION,
                    "mapping over the link is off on this server (--max-mapping-jobs 0)");
    }
    v1::MappingRequest request;
    if (!stream->Read(&request) || !request.has_start()) {
      return Status(StatusCode::INVALID_ARGUMENT, "a mapping stream starts with MappingStart");
    }
    const v1::MappingStart start = request.start();
    const std::string& name = start.map_name();
    mapstore::CheckMapName(name);
    proto::MappingJobOptions job = proto::FromProto(start.options());
    if (maps_->directory().Contains(name) && !job.replace) {
      return Status(StatusCode::ALREADY_EXISTS,
                    StrCat("a map named '", name,
                           "' already exists; build with --replace (MappingOptions.replace) to "
                           "replace it when the new one is published"));
    }
    const proto::StereoRigInput rig = proto::FromProto(start.rig(), limits_.wire);
    const JobSlot slot(&active_jobs_, limits_.max_jobs);
    if (!slot.held()) {
      return Status(StatusCode::RESOURCE_EXHAUSTED,
                    StrCat(limits_.max_jobs, " mapping job", limits_.max_jobs == 1 ? "" : "s",
                           " already running (--max-mapping-jobs); try again when it ends"));
    }
    job.builder.threads = limits_.threads;
    mapping::MapBuilder builder(rig.left, rig.right, rig.right_from_left, job.builder);
    Log("mapping_started", {{"map", name},
                            {"robot", start.robot_id()},
                            {"peer", context->peer()},
                            {"replace", job.replace ? "true" : "false"}});
    uint64_t frames = 0;
    int64_t last_timestamp_ns = 0;
    bool ended = false;
    while (stream->Read(&request)) {
      if (request.has_end()) {
        ended = true;
        break;
      }
      if (!request.has_frame()) {
        return Fail(stream, name, StatusCode::INVALID_ARGUMENT,
                    "a mapping stream has one MappingStart, then frames: nothing was published");
      }
      const Timer timer;
      const v1::StereoFrame& frame = request.frame();
      v1::MappingProgress progress;
      try {
        if (frames >= static_cast<uint64_t>(limits_.max_frames)) {
          throw InputError(StrCat("the job has its ", limits_.max_frames,
                                  " frames (--max-mapping-frames); end the stream to publish"));
        }
        if (builder.Progress().frames > 0 && frame.timestamp_ns() <= last_timestamp_ns) {
          throw InputError(StrCat("timestamp ", frame.timestamp_ns(), " ns is not after the last ",
                                  last_timestamp_ns, " ns"));
        }
        const auto [left, right] = DecodePair(frame, rig);
        builder.AddFrame(frame.timestamp_ns(), left, right);
        last_timestamp_ns = frame.timestamp_ns();
        proto::ToProto(builder.Progress(), &progress);
      } catch (const InputError& e) {
        progress.set_state(v1::MAPPING_FRAME_ERROR);
        progress.set_error(e.what());
      }
      progress.set_frame_index(frames++);
      progress.set_timestamp_ns(frame.timestamp_ns());
      progress.set_frame_ms(timer.ElapsedMs());
      if (!stream->Write(progress)) break;
    }
    if (!ended) {
      const std::string reason =
          StrCat("the mapping stream of '", name, "' broke after ", frames, " frames",
                 context->IsCancelled() ? " (the client went away)" : " (no MappingEnd)",
                 ": nothing was published");
      Log("mapping_abandoned",
          {{"map", name},
           {"frames", std::to_string(frames)},
           {"reason", context->IsCancelled() ? "the client went away" : "no MappingEnd"}});
      return Status(StatusCode::ABORTED, reason);
    }
    v1::MappingProgress finishing;
    finishing.set_state(v1::MAPPING_FINISHING);
    finishing.set_frame_index(frames);
    stream->Write(finishing);
    const mapping::MapBuilderProgress so_far = builder.Progress();
    if (so_far.frames == 0) {
      return Fail(stream, name, StatusCode::FAILED_PRECONDITION,
                  "no frame was mapped: nothing was published");
    }
    const Timer timer;
    const MapMetadata metadata{
        name, static_cast<int64_t>(std::time(nullptr)),
        StrCat("streamed by ", start.robot_id().empty() ? context->peer() : start.robot_id()),
        StrCat("visloc ", VislocVersion(), " mapping service"), ""};
    const Map map = builder.Finish(metadata);
    if (static_cast<int>(map.points.size()) < job.min_points) {
      return Fail(
          stream, name, StatusCode::FAILED_PRECONDITION,
          StrCat("the map would have ", map.points.size(), " points, fewer than ", job.min_points,
                 " (min_points) from ", so_far.frames, " frames: nothing was published"));
    }
    mapstore::MapDirectory directory = maps_->directory();  // Publish renames in its folder.
    const std::string staged = directory.StagingPathFor(name);
    mapstore::SaveMap(map, staged);
    v1::MappingProgress published;
    proto::ToProto(directory.Publish(staged, name, job.replace), published.mutable_map());
    published.set_state(v1::MAPPING_PUBLISHED);
    published.set_frame_index(frames);
    published.set_keyframes(static_cast<uint32_t>(map.keyframes.size()));
    published.set_points(map.points.size());
    published.set_tracking_failures(static_cast<uint32_t>(builder.stats().tracking_failures));
    published.set_loop_closures(static_cast<uint32_t>(builder.stats().loop_closures));
    published.set_frame_ms(timer.ElapsedMs());
    Log("map_built_over_link", {{"map", name},
                                {"frames", std::to_string(frames)},
                                {"keyframes", std::to_string(map.keyframes.size())},
                                {"points", std::to_string(map.points.size())},
                                {"finish_ms", StrCat(timer.ElapsedMs())}});
    stream->Write(published);
    return Status::OK;
  });
}

}  // namespace visloc::server
