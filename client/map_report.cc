#include "client/map_report.h"

#include <cstdio>
#include <ctime>
#include <iostream>

#include "core/camera/camera.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"

namespace visloc::cli {
void WritePoseField(JsonWriter& json, const char* key, const Rigid3d& pose) {
  json.Key(key)
      .BeginObject()
      .Field("tx", pose.translation.x())
      .Field("ty", pose.translation.y())
      .Field("tz", pose.translation.z())
      .Field("qw", pose.rotation.w())
      .Field("qx", pose.rotation.x())
      .Field("qy", pose.rotation.y())
      .Field("qz", pose.rotation.z())
      .EndObject();
}

namespace {

const char* GravitySourceText(MapGravity::Source source) {
  switch (source) {
    case MapGravity::Source::kImu:
      return "IMU";
    case MapGravity::Source::kLevelRig:
      return "level rig";
    case MapGravity::Source::kFloor:
      return "floor";
    case MapGravity::Source::kMotionPlane:
      return "motion plane";
    case MapGravity::Source::kImuAndFloor:
      return "IMU and floor";
  }
  return "unknown";
}

using mapstore::MapInfo;

std::string FormatTime(int64_t unix_s) {
  const std::time_t t = static_cast<std::time_t>(unix_s);
  std::tm utc{};
  gmtime_r(&t, &utc);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%d %H:%M:%S UTC", &utc);
  return buffer;
}

std::string FormatBytes(uint64_t bytes) {
  if (bytes >= (1u << 20)) return FormatFixed(bytes / 1048576.0, 1) + " MiB";
  if (bytes >= (1u << 10)) return FormatFixed(bytes / 1024.0, 1) + " KiB";
  return StrCat(bytes, " B");
}

std::string FormatBox(const Eigen::AlignedBox3d& box) {
  if (box.isEmpty()) return "(none)";
  return StrCat("x [", FormatFixed(box.min().x(), 2), ", ", FormatFixed(box.max().x(), 2), "] y [",
                FormatFixed(box.min().y(), 2), ", ", FormatFixed(box.max().y(), 2), "] z [",
                FormatFixed(box.min().z(), 2), ", ", FormatFixed(box.max().z(), 2), "] m");
}

void WriteBox(JsonWriter& json, const std::string& key, const Eigen::AlignedBox3d& box) {
  json.Key(key);
  if (box.isEmpty()) {
    json.Null();
    return;
  }
  json.BeginObject().Key("min").BeginArray();
  for (int i = 0; i < 3; ++i) json.Value(box.min()[i]);
  json.EndArray().Key("max").BeginArray();
  for (int i = 0; i < 3; ++i) json.Value(box.max()[i]);
  json.EndArray().EndObject();
}

void WriteInfoJson(JsonWriter& json, const MapInfo& info) {
  const Camera& c = info.camera;
  json.BeginObject()
      .Field("name", info.metadata.name)
      .Field("path", info.path)
      .Field("schema_version", info.schema_version)
      .Field("file_bytes", static_cast<int64_t>(info.file_bytes))
      .Field("created_unix_s", info.metadata.created_unix_s)
      .Field("source_dataset", info.metadata.source_dataset)
      .Field("builder", info.metadata.builder)
      .Field("lineage", info.metadata.lineage)
      .Key("disparity_correction");
  if (const auto& correction = info.metadata.disparity_correction) {
    json.BeginObject()
        .Field("offset_px", correction->offset_px)
        .Field("right_camera_yaw_deg", correction->yaw_deg())
        .EndObject();
  } else {
    json.Null();
  }
  json.Key("rig_error");
  if (const auto& rig = info.metadata.rig_error) {
    json.BeginObject()
        .Field("floor_m", rig->floor_m)
        .Field("drift_fraction", rig->drift_fraction)
        .EndObject();
  } else {
    json.Null();
  }
  json.Key("stereo_baseline_m");
  if (const auto& baseline_m = info.metadata.stereo_baseline_m) {
    json.Value(*baseline_m);
  } else {
    json.Null();
  }
  json.Key("gravity");
  if (const auto& gravity = info.metadata.gravity) {
    json.BeginObject().Key("up_in_map").BeginArray();
    for (int i = 0; i < 3; ++i) json.Value(gravity->up_in_map[i]);
    json.EndArray()
        .Field("sigma_deg", gravity->sigma_deg)
        .Field("source", GravitySourceName(gravity->source))
        .Field("map_frame_tilt_deg", MapFrameTiltDeg(*gravity))
        .EndObject();
  } else {
    json.Null();
  }
  json.Key("site");
  if (const std::optional<Rigid3d> site_from_map = SiteFromMap(info.metadata)) {
    const auto& site = info.metadata.site;
    json.BeginObject().Field("frame", site ? "aligned" : "level");
    WritePoseField(json, "site_from_map", *site_from_map);
    if (site) {
      json.Field("pairs", site->pairs)
          .Field("rms_m", site->rms_m)
          .Field("max_residual_m", site->max_residual_m)
          .Field("reference", site->reference);
    }
    json.EndObject();
  } else {
    json.Null();
  }
  json.Key("camera")
      .BeginObject()
      .Field("model", mapstore::CameraModelName(c.lens().model))
      .Field("lens_model", LensModelName(c.lens().model))
      .Field("width", c.width())
      .Field("height", c.height());
  const auto lens_names = LensCoefficientNames(c.lens().model);
  const char* names[8] = {"fx",          "fy",          "cx",          "cy",
                          lens_names[0], lens_names[1], lens_names[2], lens_names[3]};
  const auto params = c.Params();
  for (int i = 0; i < 8; ++i) json.Field(names[i], params[i]);
  json.EndObject()
      .Key("features")
      .BeginObject()
      .Field("kind", info.features.kind)
      .Field("descriptor_type", ToString(info.features.descriptor_type))
      .Field("descriptor_dim", info.features.descriptor_dim)
      .EndObject()
      .Field("keyframes", static_cast<int64_t>(info.keyframes))
      .Field("points", static_cast<int64_t>(info.points))
      .Field("observations", static_cast<int64_t>(info.observations))
      .Field("mean_reproj_error_px", info.mean_reproj_error_px);
  WriteBox(json, "point_extent_m", info.point_extent);
  WriteBox(json, "keyframe_extent_m", info.keyframe_extent);
  json.Key("visibility_kernel")
      .BeginObject()
      .Field("learned", info.kernel_learned)
      .Field("default_k", info.kernel.default_k)
      .Field("default_probability_threshold", info.kernel.default_probability_threshold)
      .EndObject()
      .Field("vocabulary_words", static_cast<int64_t>(info.vocabulary_words))
      .Field("memory_bytes", static_cast<int64_t>(info.memory_bytes))
      .EndObject();
}

void PrintInfo(const MapInfo& info) {
  std::printf("map           %s (schema %d, %s, %s)\n", info.metadata.name.c_str(),
              info.schema_version, FormatBytes(info.file_bytes).c_str(), info.path.c_str());
  std::printf("created       %s from %s by %s\n", FormatTime(info.metadata.created_unix_s).c_str(),
              info.metadata.source_dataset.c_str(), info.metadata.builder.c_str());
  if (!info.metadata.lineage.empty()) {
    std::printf("lineage       %s\n", info.metadata.lineage.c_str());
  }
  std::printf("camera        %s\n", ToString(info.camera).c_str());
  if (const auto& correction = info.metadata.disparity_correction) {
    std::printf(
        "stereo rig    disparity offset %.3f px, right camera yaw %.4f deg (taken off its "
        "disparities; map build --disparity-correction-from takes it)\n",
        correction->offset_px, correction->yaw_deg());
  }
  if (const auto& rig = info.metadata.rig_error) {
    std::printf("rig error     %.2f mm + %.2f%% of the distance from the origin, per axis (its "
                "calibration's, in every fix's covariance)\n",
                1e3 * rig->floor_m, 100 * rig->drift_fraction);
  }
  if (const auto& baseline_m = info.metadata.stereo_baseline_m) {
    std::printf("stereo        baseline %.1f mm (how well its points are known, in every fix's "
                "covariance)\n",
                1e3 * *baseline_m);
  }
  if (const auto& gravity = info.metadata.gravity) {
    const Eigen::Vector3d& up = gravity->up_in_map;
    std::printf(
        "up            (%.4f, %.4f, %.4f) in the map frame, from the %s, sigma %.2f deg; "
        "the map frame is %.1f deg off level\n",
        up.x(), up.y(), up.z(), GravitySourceText(gravity->source), gravity->sigma_deg,
        MapFrameTiltDeg(*gravity));
  } else {
    std::printf("up            not known (no IMU, level rig or floor told the build)\n");
  }
  if (const auto& site = info.metadata.site) {
    std::printf("site          tied to %s by %d pairs, residual %.2f cm rms, %.2f cm at most\n",
                site->reference.c_str(), site->pairs, 100 * site->rms_m,
                100 * site->max_residual_m);
  } else if (info.metadata.gravity) {
    std::printf(
        "site          the map's level frame (z up, x the first camera's heading, origin "
        "at it); visloc map align ties it to the site's own\n");
  } else {
    std::printf("site          none: the map knows no up (visloc map align ties it to one)\n");
  }
  std::printf("features      %s (%s x %d)\n", info.features.kind.c_str(),
              ToString(info.features.descriptor_type).c_str(), info.features.descriptor_dim);
  std::printf("keyframes     %zu, centres %s\n", info.keyframes,
              FormatBox(info.keyframe_extent).c_str());
  std::printf("points        %zu, %s, mean reprojection error %.2f px\n", info.points,
              FormatBox(info.point_extent).c_str(), info.mean_reproj_error_px);
  std::printf("observations  %zu (%.1f per point)\n", info.observations,
              info.points ? static_cast<double>(info.observations) / info.points : 0.0);
  std::printf("visibility    %s; K = %d, P_t = %.2f\n",
              info.kernel_learned ? "learned kernel" : "no learned kernel", info.kernel.default_k,
              info.kernel.default_probability_threshold);
  std::printf("vocabulary    %zu words\n", info.vocabulary_words);
  std::printf("memory        %s when loaded for localization\n",
              FormatBytes(info.memory_bytes).c_str());
}

}  // namespace

int PrintMapInfo(const MapInfo& info, bool json) {
  if (!json) {
    PrintInfo(info);
    return 0;
  }
  JsonWriter writer;
  WriteInfoJson(writer, info);
  std::cout << writer.str() << "\n";
  return 0;
}

int PrintMapList(const std::vector<mapstore::MapDirectory::Entry>& entries,
                 const std::string& where, bool json) {
  if (json) {
    JsonWriter writer;
    writer.BeginArray();
    for (const auto& entry : entries) {
      if (entry.info) {
        WriteInfoJson(writer, *entry.info);
      } else {
        writer.BeginObject()
            .Field("name", entry.name)
            .Field("path", entry.path)
            .Field("error", entry.error)
            .EndObject();
      }
    }
    writer.EndArray();
    std::cout << writer.str() << "\n";
    return 0;
  }
  std::printf("%-24s %10s %10s %12s %10s  %s\n", "NAME", "KEYFRAMES", "POINTS", "SIZE", "CREATED",
              "FEATURES");
  for (const auto& entry : entries) {
    if (entry.info) {
      std::printf("%-24s %10zu %10zu %12s %10s  %s\n", entry.name.c_str(), entry.info->keyframes,
                  entry.info->points, FormatBytes(entry.file_bytes).c_str(),
                  FormatTime(entry.info->metadata.created_unix_s).substr(0, 10).c_str(),
                  entry.info->features.kind.c_str());
    } else {
      std::printf("%-24s unavailable: %s\n", entry.name.c_str(), entry.error.c_str());
    }
  }
  std::printf("%zu maps %s\n", entries.size(), where.c_str());
  return 0;
}

}  // namespace visloc::cli
