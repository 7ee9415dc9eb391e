#include "sim/generate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <future>
#include <set>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "core/util/timer.h"
#include "dataset/euroc.h"
#include "dataset/kitti.h"
#include "dataset/tum.h"
#include "sim/renderer.h"
#include "sim/sensors.h"

namespace visloc::sim {
namespace fs = std::filesystem;
namespace {

std::string WorldKey(const RoomOptions& room) {
  return StrCat(room.seed, "/", static_cast<int>(room.layout), "/", room.people, "/", room.width_m,
                "x", room.depth_m, "x", room.height_m, "/", room.texel_m, "/", room.suite, "/",
                room.street, "/", room.building);
}

// The two views of a stereo frame; with two threads rendered at once, the right one on a second
// thread: rendering is most of a sequence's time, and it reads the world only. The sensor's
// noise is drawn after, in frame order, so a sequence is the same image for image either way.
template <typename RenderLeft, typename RenderRight>
void RenderPair(int threads, RenderLeft render_left, RenderRight render_right, cv::Mat* left,
                cv::Mat* right) {
  if (threads < 2) {
    *left = render_left();
    *right = render_right();
    return;
  }
  std::future<cv::Mat> right_done = std::async(std::launch::async, render_right);
  *left = render_left();
  *right = right_done.get();
}

bool Within(const std::vector<std::pair<double, double>>& intervals, double t) {
  for (const auto& [start, end] : intervals) {
    if (t >= start && t < end) return true;
  }
  return false;
}

// Six frames spread over the sequence; where the camera gets covered, the middle covered frame
// and the first frame after the cover replace two of them, so a look shows the event.
std::set<int> ContactSheetFrames(const SequenceSpec& spec, int frame_count, double fps) {
  std::vector<int> frames;
  for (int i = 0; i < 6; ++i) frames.push_back(i * (frame_count - 1) / 5);
  if (!spec.covered_s.empty()) {
    const auto [start, end] = spec.covered_s.front();
    const int covered = static_cast<int>(std::ceil(0.5 * (start + end) * fps));
    const int after = static_cast<int>(std::ceil(end * fps));
    if (after < frame_count) {
      frames[2] = covered;
      frames[3] = after;
    }
  }
  return std::set<int>(frames.begin(), frames.end());
}

cv::Mat MakeContactSheet(const std::vector<std::pair<std::string, cv::Mat>>& tiles) {
  VISLOC_CHECK(!tiles.empty(), "no tiles");
  const int cols = 3, rows = static_cast<int>((tiles.size() + cols - 1) / cols);
  const int w = tiles[0].second.cols, h = tiles[0].second.rows;
  cv::Mat sheet(rows * (h + 4), cols * (w + 4), CV_8UC1, cv::Scalar(255));
  for (size_t i = 0; i < tiles.size(); ++i) {
    const cv::Rect where((i % cols) * (w + 4) + 2, (i / cols) * (h + 4) + 2, w, h);
    tiles[i].second.copyTo(sheet(where));
    const double scale = std::max(0.35, w / 900.0);
    cv::putText(sheet, tiles[i].first,
                where.tl() + cv::Point(4, static_cast<int>(18 * scale / 0.45)),
                cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0), 3, cv::LINE_AA);
    cv::putText(sheet, tiles[i].first,
                where.tl() + cv::Point(4, static_cast<int>(18 * scale / 0.45)),
                cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255), 1, cv::LINE_AA);
  }
  return sheet;
}

// The auto-exposure's gain at time t: a slow swing plus steps every few seconds, as a camera
// that keeps re-metering a scene of changing brightness.
double AutoExposureGain(const CameraEffects& effects, double t, uint64_t seed) {
  const double phase = 0.7 * static_cast<double>(seed % 9);
  const double swing = std::sin(2 * M_PI * t / 6.3 + phase);
  const double step = std::sin(2 * M_PI * t / 2.7 + 1.0 + phase) > 0 ? 1.0 : -1.0;
  return 1.0 + effects.auto_exposure * (0.6 * swing + 0.4 * step);
}

}  // namespace

void CameraEffects::Check() const {
  VISLOC_CHECK(auto_exposure >= 0 && auto_exposure < 1 && vignetting >= 0 && vignetting < 1 &&
                   exposure_time_s >= 0 && exposure_time_s < 0.1 && right_exposure_ratio > 0,
               "camera effects");
}

SequenceGenerator::SequenceGenerator(const GenerateOptions& options) : options_(options) {
  VISLOC_CHECK(options.max_frames >= 0, "max_frames ", options.max_frames);
  if (options.effects) options.effects->Check();
}

const World& SequenceGenerator::WorldFor(const RoomOptions& room) {
  auto& slot = worlds_[WorldKey(room)];
  if (!slot) slot = std::make_unique<World>(room.street ? MakeStreet(room) : MakeRoom(room));
  return *slot;
}

GenerateStats SequenceGenerator::Generate(const std::string& name, const std::string& out_dir,
                                          const std::function<void(int, int)>& progress) {
  const SequenceSpec spec = MakeSequenceSpec(name, options_.seed);
  const RigOptions rig_options = spec.car ? CarRig(options_.rig) : options_.rig;
  const StereoRig rig = MakeRig(rig_options);
  const World& world = WorldFor(spec.room);
  const Rigid3d map_from_world =
      spec.car ? (spec.path.WorldFromBody(0.0) * rig.left.body_from_cam).Inverse()
               : WorldFromMap(rig_options).Inverse();
  // The right camera as it really is: turned against its calibration by the rig's yaw error.
  const Rigid3d calibrated_from_true_right(
      Eigen::Quaterniond(Eigen::AngleAxisd(rig_options.right_yaw_error_deg * M_PI / 180.0,
                                           Eigen::Vector3d::UnitY())),
      Eigen::Vector3d::Zero());

  GenerateStats stats;
  stats.name = name;
  stats.dir = (fs::path(out_dir) / name).string();
  int frame_count = static_cast<int>(std::floor(spec.path.duration_s() * rig_options.fps)) + 1;
  if (options_.max_frames > 0) frame_count = std::min(frame_count, options_.max_frames);
  stats.frames = frame_count;
  fs::remove_all(stats.dir);
  fs::create_directories(stats.dir);

  const std::vector<CameraInfo> others = OtherCameras(rig_options, rig);
  std::unique_ptr<EurocWriter> euroc;
  if (options_.format == DatasetFormat::kEuroc) {
    euroc = std::make_unique<EurocWriter>(stats.dir, rig.left, rig.right);
    for (size_t c = 0; c < others.size(); ++c) {
      euroc->AddCamera(others[c],
                       StrCat(RigLayoutName(rig_options.layout), " rig's camera ", c + 2));
    }
  } else {
    VISLOC_CHECK(others.empty(), "a rig's further cameras are written in the EuRoC layout only");
    VISLOC_CHECK(!rig_options.distortion && !rig_options.fisheye && !rig_options.imperfect,
                 "KITTI sequences are rectified: no distortion, fisheye or imperfect rig");
    WriteKittiCalibration(stats.dir, rig.left.camera, rig_options.baseline_m);
  }

  const Renderer left_renderer(rig.left.camera, options_.supersample);
  const Renderer right_renderer(rig.right.camera, options_.supersample);
  const Renderer other_renderer(rig.left.camera, options_.supersample);  // Same lens.
  Rng noise(options_.seed * 1000003 + std::hash<std::string>{}(name) % 1000);
  std::vector<double> times_s;
  std::vector<int64_t> stamps_ns;
  Trajectory world_from_body, map_from_cam;
  std::vector<int> covered_frames, blank_frames;
  std::vector<std::pair<std::string, cv::Mat>> sheet;
  const std::set<int> sheet_frames = ContactSheetFrames(spec, frame_count, rig_options.fps);
  Timer render_timer;
  double render_ms = 0;
  for (int k = 0; k < frame_count; ++k) {
    const double t = k / rig_options.fps;
    const int64_t stamp = options_.start_ns + static_cast<int64_t>(std::llround(t * 1e9));
    const Rigid3d body = spec.path.WorldFromBody(t);
    const Rigid3d world_from_left = body * rig.left.body_from_cam;
    const Rigid3d world_from_right = body * rig.right.body_from_cam * calibrated_from_true_right;
    cv::Mat left_radiance, right_radiance;
    render_timer.Restart();
    if (Within(spec.covered_s, t)) {
      // A hand over the lens lets a little light through: dark, flat, noisy.
      left_radiance =
          cv::Mat(rig.left.camera.height(), rig.left.camera.width(), CV_32FC1, cv::Scalar(0.015));
      right_radiance = left_radiance.clone();
      covered_frames.push_back(k);
    } else if (Within(spec.blank_s, t)) {
      // A blank wall fills the view: evenly lit, no texture; the sensor adds its noise.
      left_radiance =
          cv::Mat(rig.left.camera.height(), rig.left.camera.width(), CV_32FC1, cv::Scalar(0.45));
      right_radiance = left_radiance.clone();
      blank_frames.push_back(k);
    } else if (options_.effects) {
      // The shutter opens half the exposure time before t and closes half after.
      const double half = 0.5 * options_.effects->exposure_time_s;
      const Rigid3d open = spec.path.WorldFromBody(t - half),
                    close = spec.path.WorldFromBody(t + half);
      RenderPair(
          options_.render_threads,
          [&] {
            return left_renderer.RenderRadiance(world, open * rig.left.body_from_cam,
                                                close * rig.left.body_from_cam, t, 2 * half);
          },
          [&] {
            return right_renderer.RenderRadiance(
                world, open * rig.right.body_from_cam * calibrated_from_true_right,
                close * rig.right.body_from_cam * calibrated_from_true_right, t, 2 * half);
          },
          &left_radiance, &right_radiance);
    } else {
      RenderPair(
          options_.render_threads,
          [&] { return left_renderer.RenderRadiance(world, world_from_left, t); },
          [&] { return right_renderer.RenderRadiance(world, world_from_right, t); }, &left_radiance,
          &right_radiance);
    }
    render_ms += render_timer.ElapsedMs();
    SensorModel left_sensor = spec.sensor, right_sensor = spec.sensor;
    if (options_.effects) {
      const double gain = AutoExposureGain(*options_.effects, t, options_.seed);
      left_sensor.exposure *= gain;
      right_sensor.exposure *= gain * options_.effects->right_exposure_ratio;
      left_sensor.vignetting = right_sensor.vignetting = options_.effects->vignetting;
    }
    const cv::Mat left = left_sensor.Capture(left_radiance, &noise);
    const cv::Mat right = right_sensor.Capture(right_radiance, &noise);
    // The further cameras see the room as it is: a hand covers the front pair only.
    std::vector<cv::Mat> other_images;
    for (const CameraInfo& other : others) {
      render_timer.Restart();
      const cv::Mat radiance =
          options_.effects
              ? other_renderer.RenderRadiance(
                    world,
                    spec.path.WorldFromBody(t - 0.5 * options_.effects->exposure_time_s) *
                        other.body_from_cam,
                    spec.path.WorldFromBody(t + 0.5 * options_.effects->exposure_time_s) *
                        other.body_from_cam,
                    t, options_.effects->exposure_time_s)
              : other_renderer.RenderRadiance(world, body * other.body_from_cam, t);
      render_ms += render_timer.ElapsedMs();
      other_images.push_back(left_sensor.Capture(radiance, &noise));
    }
    if (euroc) {
      euroc->AddFrame(stamp, left, right, other_images);
    } else {
      WriteKittiFrame(stats.dir, k, left, right);
    }
    if (options_.contact_sheet && sheet_frames.count(k)) {
      sheet.emplace_back(StrCat(name, " #", k, " t=", FormatFixed(t, 1), "s"), left);
    }
    times_s.push_back(t);
    stamps_ns.push_back(stamp);
    world_from_body.push_back({stamp, body});
    map_from_cam.push_back({stamp, map_from_world * world_from_left});
    if (progress) progress(k + 1, frame_count);
  }
  stats.covered_frames = static_cast<int>(covered_frames.size());
  // What was rendered, which max_frames may have cut short of the whole walk: its duration, and
  // the distance walked between its frames (carried stretches left out, as length_m() does).
  stats.duration_s = times_s.back();
  for (size_t k = 1; k < times_s.size(); ++k) {
    if (!spec.path.SteppingAt(times_s[k])) continue;
    const PlanarPose a = spec.path.PlannedAt(times_s[k - 1]), b = spec.path.PlannedAt(times_s[k]);
    stats.path_length_m += std::hypot(b.x - a.x, b.y - a.y);
  }
  stats.render_ms_per_frame = render_ms / std::max(1, frame_count);

  const Trajectory odom_from_cam =
      SynthesizeOdometry(spec.path, rig.left.body_from_cam, times_s, options_.start_ns,
                         OdometryDrift{}, options_.seed);
  if (euroc) {
    std::vector<ImuSample> imu =
        SynthesizeImu(spec.path, options_.start_ns, ImuNoise{}, options_.seed);
    const int64_t last = stamps_ns.back();
    imu.erase(std::remove_if(imu.begin(), imu.end(),
                             [&](const ImuSample& s) { return s.timestamp_ns > last; }),
              imu.end());
    euroc->Finish(imu, odom_from_cam, world_from_body);
  } else {
    WriteKittiTimesAndPoses(stats.dir, stamps_ns,
                            RelativeTo(map_from_cam, map_from_cam.front().pose));
  }
  WriteTum(stats.dir + "/groundtruth_map.tum", map_from_cam);
  // Dead reckoning from the true start: the odometry's motion applied to the first frame's
  // true pose, in the map frame. The baseline a localizer must beat.
  const Rigid3d map_from_odom = map_from_cam.front().pose * odom_from_cam.front().pose.Inverse();
  Trajectory odometry_in_map;
  for (const StampedPose& p : odom_from_cam)
    odometry_in_map.push_back({p.timestamp_ns, map_from_odom * p.pose});
  WriteTum(stats.dir + "/odometry_map.tum", odometry_in_map);

  JsonWriter json;
  json.BeginObject()
      .Field("name", name)
      .Field("description", spec.description)
      .Field("format", ToString(options_.format))
      .Field("frames", frame_count)
      .Field("fps", rig_options.fps)
      .Field("width", rig_options.width)
      .Field("height", rig_options.height)
      .Field("distortion", rig_options.distortion)
      .Field("lens", rig_options.fisheye ? "fisheye" : "pinhole")
      .Field("imperfect_rig", rig_options.imperfect)
      .Field("right_yaw_error_deg", rig_options.right_yaw_error_deg)
      .Field("camera_pitch_deg", rig_options.camera_pitch_deg)
      .Field("camera_roll_deg", rig_options.camera_roll_deg)
      .Field("camera_effects", options_.effects.has_value())
      .Field("rig", RigLayoutName(rig_options.layout))
      .Field("seed", static_cast<int64_t>(options_.seed))
      .Field("duration_s", times_s.back())
      .Field("path_length_m", stats.path_length_m)
      .Key("covered_frames")
      .BeginArray();
  for (int k : covered_frames) json.Value(k);
  json.EndArray().Key("blank_frames").BeginArray();
  for (int k : blank_frames) json.Value(k);
  json.EndArray().EndObject();
  WriteFileAtomically(stats.dir + "/sequence.json", json.str() + "\n");
  std::string why;
  if (!sheet.empty() &&
      !image::WritePng(stats.dir + "/contact_sheet.png", MakeContactSheet(sheet), 1, &why)) {
    throw InputError(why);
  }
  return stats;
}

}  // namespace visloc::sim
