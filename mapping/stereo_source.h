#pragma once
// A stereo recording as the mapping pipelines read it: a calibrated rig and its frames in order,
// read by index (a pipeline may read them more than once, as extend and update do: the left
// images localized in the map first, then every pair mapped). The mapping layer knows no file
// format: a dataset folder (dataset_source.h), frames kept by a server, or a test's rendered
// images are all a StereoSource.

#include <cstdint>
#include <functional>
#include <string>

#include <opencv2/core.hpp>

#include "core/camera/camera.h"
#include "core/geometry/rigid3.h"
#include "core/geometry/trajectory.h"
#include "core/map/map.h"
#include "mapping/map_builder.h"

namespace visloc::mapping {

// One stereo frame: raw 8-bit grey images of the rig's calibrated sizes.
struct StereoImages {
  int64_t timestamp_ns = 0;
  cv::Mat left_raw;
  cv::Mat right_raw;
};

class StereoSource {
 public:
  virtual ~StereoSource() = default;

  // Named in errors and in a map's metadata ("the session NAME ..."), e.g. the dataset folder.
  virtual std::string name() const = 0;
  // Where the frames come from, kept in a map's metadata (MapMetadata::source_dataset); by
  // default the name.
  virtual std::string origin() const { return name(); }
  virtual const Camera& left_camera() const = 0;
  virtual const Camera& right_camera() const = 0;
  virtual Rigid3d right_from_left() const = 0;
  virtual int size() const = 0;
  virtual int64_t TimestampNs(int index) const = 0;
  // Throws InputError naming the frame when an image cannot be read. Mapping with more than one
  // thread reads the next frame while it maps this one: one Read at a time, not always on the
  // caller's thread.
  virtual StereoImages Read(int index) const = 0;
  // The left image alone (localization needs no right image); by default Read(index).left_raw.
  virtual cv::Mat ReadLeft(int index) const { return Read(index).left_raw; }

  // `progress(done, total, status)` per frame while mapping.
  using MappingProgress = std::function<void(int, int, const std::string&)>;
  // Every frame through a MapBuilder, then the map. A source that can say more about a rig that
  // does not map (a dataset: its check, the stereo evidence) overrides this (dataset_mapping.h).
  virtual Map BuildMap(const MapBuilderOptions& options, const MapMetadata& metadata,
                       MapBuildStats* stats, Trajectory* frame_trajectory,
                       const MappingProgress& progress) const;
};

// Every frame of `source` through one MapBuilder: the map, and optionally the builder's stats
// (total_ms set) and the raw left camera's pose per frame. `progress` as for StereoSource. With
// options.threads other than 1, frame i + 1 is read (decoded) and prepared (its features and
// rectification, MapBuilder::Prepare) while frame i is mapped.
Map MapStereoFrames(const StereoSource& source, const MapBuilderOptions& options,
                    const MapMetadata& metadata, MapBuildStats* stats = nullptr,
                    Trajectory* frame_trajectory = nullptr,
                    const StereoSource::MappingProgress& progress = nullptr);

}  // namespace visloc::mapping
