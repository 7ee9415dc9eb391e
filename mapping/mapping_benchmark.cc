// Microbenchmarks of map building's stereo frames and bundle adjustment (Google Benchmark). Run:
//   build/mapping/mapping_benchmark
// Speed is measured here, never asserted in tests. The input is synthetic and deterministic: a
// rectified stereo rig (KITTI's geometry: 718 px, 0.54 m) driving forward a metre a keyframe
// through points at 5-60 m, each keyframe observing the points in its view with 0.3 px of
// keypoint noise and 0.05 px of disparity noise, a fifth of them without a right match.

#include <benchmark/benchmark.h>

#include <cmath>

#include "core/features/features.h"
#include "core/geometry/rigid3.h"
#include "core/util/random.h"
#include "mapping/bundle_adjustment.h"
#include "mapping/keyframes.h"
#include "mapping/stereo_frame.h"
#include "sim/sequences.h"
#include "sim/world.h"

namespace visloc::mapping {
namespace {

constexpr int kWidth = 1241, kHeight = 376;
const RectifiedIntrinsics kRig{718.0, 607.0, 185.0, 0.54};

// `keyframes` keyframes a metre apart along +z, the poses and points perturbed off the truth
// (1 cm, 0.1 deg; 2% of depth) as tracking would leave them.
SlamState DrivingWindow(int keyframes) {
  Rng rng(11);
  SlamState state;
  std::vector<Eigen::Vector3d> truth;
  for (int p = 0; p < 150 * keyframes; ++p) {
    truth.emplace_back(rng.Uniform(-25.0, 25.0), rng.Uniform(-4.0, 2.0),
                       rng.Uniform(5.0, 60.0 + keyframes));
  }
  state.landmarks.resize(truth.size());
  for (int k = 0; k < keyframes; ++k) {
    const Rigid3d true_cam_from_world(Eigen::Quaterniond::Identity(),
                                      Eigen::Vector3d(0.0, 0.0, -static_cast<double>(k)));
    SlamKeyframe keyframe;
    keyframe.cam_from_world = k == 0 ? true_cam_from_world
                                     : Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(
                                                   0.002, Eigen::Vector3d::UnitY())),
                                               true_cam_from_world.translation +
                                                   Eigen::Vector3d::Constant(0.01));
    state.keyframes.push_back(keyframe);
    for (size_t l = 0; l < truth.size(); ++l) {
      const Eigen::Vector3d p = true_cam_from_world * truth[l];
      if (p.z() < 5.0 || p.z() > 60.0) continue;
      const Eigen::Vector2d pixel(kRig.f * p.x() / p.z() + kRig.cx, kRig.f * p.y() / p.z() + kRig.cy);
      if (pixel.x() < 0 || pixel.x() >= kWidth || pixel.y() < 0 || pixel.y() >= kHeight) continue;
      SlamKeyframe& kf = state.keyframes.back();
      kf.left_rect.push_back(pixel + Eigen::Vector2d(rng.Normal(0, 0.3), rng.Normal(0, 0.3)));
      const double disparity = kRig.f * kRig.baseline_m / p.z() + rng.Normal(0, 0.05);
      kf.right_x_rect.push_back(rng.Uniform(0.0, 1.0) < 0.2 ? std::nan("")
                                                             : kf.left_rect.back().x() - disparity);
      kf.landmark.push_back(-1);
      state.Observe(static_cast<int>(l), k, static_cast<int>(kf.landmark.size()) - 1);
    }
  }
  for (size_t l = 0; l < truth.size(); ++l) {
    state.landmarks[l].position_in_world = truth[l] * (1.0 + rng.Normal(0, 0.02));
    state.landmarks[l].culled = state.landmarks[l].observations.empty();
  }
  return state;
}

// A local bundle adjustment as the builder runs it after each keyframe: a window of 10, the
// last 3 free.
void BM_LocalBundleAdjust(benchmark::State& state) {
  const SlamState window = DrivingWindow(10);
  int residuals = 0;
  for (auto _ : state) {
    state.PauseTiming();
    SlamState copy = window;
    state.ResumeTiming();
    LocalBundleAdjust(&copy, KeyframeOptions{}, kRig, BundleAdjustmentOptions{});
    benchmark::DoNotOptimize(copy.keyframes.back().cam_from_world);
  }
  for (const Landmark& l : window.landmarks) residuals += static_cast<int>(l.observations.size());
  state.counters["observations"] = residuals;
}
BENCHMARK(BM_LocalBundleAdjust)->Unit(benchmark::kMillisecond);

// A global bundle adjustment of N keyframes (all but the first free), estimating the rig's
// disparity correction as the builder's calibration does (argument 1) or not (0).
void BM_GlobalBundleAdjust(benchmark::State& state) {
  const SlamState all = DrivingWindow(static_cast<int>(state.range(0)));
  std::vector<int> free;
  for (int k = 1; k < static_cast<int>(all.keyframes.size()); ++k) free.push_back(k);
  BundleAdjustmentOptions options;
  options.max_iterations = 40;
  options.estimate_disparity_correction = state.range(1) != 0;
  int iterations = 0;
  for (auto _ : state) {
    state.PauseTiming();
    SlamState copy = all;
    state.ResumeTiming();
    iterations = BundleAdjust(&copy, free, {0}, kRig, options).iterations;
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_GlobalBundleAdjust)
    ->Args({30, 0})
    ->Args({30, 1})
    ->Args({60, 0})
    ->Unit(benchmark::kMillisecond);

// One frame of a map build's stereo matching at 320x240 (the generated head's rig in the
// generated room): the left image's features, rectification, the row searches and (argument:
// the refinement's patch radius, 0 for none) the disparity refinement, on one thread. The ratio
// of the two is what refinement costs.
void BM_BuildStereoFrame(benchmark::State& state) {
  const sim::StereoRig rig = sim::MakeRig(sim::RigOptions{});
  sim::RoomOptions room;
  room.texel_m = 0.006;
  const sim::World world = sim::MakeRoom(room);
  const Rigid3d body(RotationFromRollPitchYaw(0, 0.02, 0.4), Eigen::Vector3d(-0.5, -0.6, 1.45));
  Rng noise(1);
  const sim::StereoShot shot = sim::RenderStereoShot(world, rig, body, sim::SensorModel{}, &noise);
  const StereoRectifier rectifier(rig.left.camera, rig.right.camera,
                                  rig.right.body_from_cam.Inverse() * rig.left.body_from_cam);
  const auto extractor = CreateFeatureExtractor(DefaultFeatureSettings("harris_surf16"));
  StereoMatchOptions options;
  options.refine_patch_radius_px = static_cast<int>(state.range(0));
  int matches = 0;
  for (auto _ : state) {
    matches =
        BuildStereoFrame(shot.left, shot.right, *extractor, rectifier, options).stereo_matches();
  }
  state.counters["matches"] = matches;
}
BENCHMARK(BM_BuildStereoFrame)->Arg(0)->Arg(7)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visloc::mapping

BENCHMARK_MAIN();
