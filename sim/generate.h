#pragma once
// Renders catalogue sequences to disk.
//
// Each sequence folder holds the dataset (EuRoC layout by default, or KITTI), plus:
//   groundtruth_map.tum   the left camera's true pose in the map frame, one line per frame
//   odometry_map.tum      dead reckoning: the odometry's motion started from the first frame's
//                         true pose, in the map frame (the baseline a localizer must beat)
//   sequence.json         what was generated: name, description, frames, covered frames, ...
//   contact_sheet.png     six left frames spread over the sequence, for a quick look

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "dataset/dataset.h"
#include "sim/sequences.h"

namespace visloc::sim {

// What real cameras add to the rendered scene: auto-exposure that keeps changing (a slow swing
// and sudden steps), vignetting, motion blur over the exposure time, and two sensors that never
// agree on brightness. Features, stereo matching and tracking must take all of it.
struct CameraEffects {
  double auto_exposure = 0.3;         // Exposure swings within 1 -+ this fraction.
  double vignetting = 0.3;            // Light lost at the image corners.
  double exposure_time_s = 0.015;     // The shutter is open this long: motion blur.
  double right_exposure_ratio = 0.9;  // The right camera's exposure against the left's.
  void Check() const;
};

struct GenerateOptions {
  RigOptions rig;
  std::optional<CameraEffects> effects;  // None: the ideal sensor of each sequence.
  int supersample = 2;  // Samples per pixel side.
  // 2: a stereo frame's two views render at once, on two threads (the same images). 1 by default:
  // the tests' data is rendered beside other tests, and a long run is the one that wants both.
  int render_threads = 1;
  int max_frames = 0;   // 0: the whole sequence.
  uint64_t seed = 1;    // Textures, noise and drift.
  DatasetFormat format = DatasetFormat::kEuroc;
  bool contact_sheet = true;
  int64_t start_ns = 1'700'000'000'000'000'000;  // Timestamp of the first frame.
};

struct GenerateStats {
  std::string name;
  std::string dir;
  int frames = 0;
  int covered_frames = 0;
  double duration_s = 0;
  double path_length_m = 0;
  double render_ms_per_frame = 0;  // Both cameras.
};

// Builds each distinct world once and reuses it across sequences.
class SequenceGenerator {
 public:
  explicit SequenceGenerator(const GenerateOptions& options);
  // Writes sequence `name` into `out_dir`/`name`. `progress(done, total)` is called per frame.
  GenerateStats Generate(const std::string& name, const std::string& out_dir,
                         const std::function<void(int, int)>& progress = nullptr);

 private:
  const World& WorldFor(const RoomOptions& room);
  GenerateOptions options_;
  std::map<std::string, std::unique_ptr<World>> worlds_;
};

}  // namespace visloc::sim
