// Maps across sessions (mapping/map_merge.h):
//   `visloc map merge A.db B.db --out C.db`  two maps of overlapping places into one, in A's frame;
//   `visloc map extend MAP.db --dataset DIR`  a new stereo session mapped, its images localized
//                                             in MAP, then merged into MAP in MAP's frame
//                                             (mapping/session_merge.h);
//   `visloc map update MAP.db --dataset DIR`  the same for a place that changed: what is gone
//                                             removed first (mapping/map_update.h).
// Maps or sessions with no verified overlap are refused with the evidence; files are written
// atomically, so the old map stays intact until the new one is complete.

#include <cstdio>
#include <functional>
#include <iostream>

#include "client/commands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "dataset/dataset.h"
#include "mapping/dataset_mapping.h"
#include "mapping/map_merge.h"
#include "mapping/session_merge.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

// `session`: how a new session's images localized in the map (extend, update); `update`: the
// update's point check, when there was one.
std::string ToJson(const std::string& out, const Map& merged, const mapping::MergeStats& s,
                   const mapping::SessionRegistrationStats* session = nullptr,
                   const mapping::UpdateStats* update = nullptr) {
  const Eigen::Vector3d& t = s.a_from_b.translation;
  const Eigen::Quaterniond& q = s.a_from_b.rotation;
  JsonWriter json;
  json.BeginObject()
      .Field("map", out)
      .Field("name", merged.metadata.name)
      .Field("lineage", merged.metadata.lineage)
      .Field("matches", s.matches)
      .Field("inliers", s.inliers)
      .Field("inlier_rmse_m", s.inlier_rmse_m)
      .Key("a_from_b")
      .BeginArray();
  for (double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) json.Value(v);
  json.EndArray()
      .Field("keyframes_a", s.keyframes_a)
      .Field("keyframes_b", s.keyframes_b)
      .Field("points_a", s.points_a)
      .Field("points_b", s.points_b)
      .Field("fused_points", s.fused_points)
      .Field("added_points", s.added_points)
      .Field("keyframes", static_cast<int64_t>(merged.keyframes.size()))
      .Field("points", static_cast<int64_t>(merged.points.size()))
      .Field("adjusted_keyframes", s.adjustment.free_keyframes)
      .Field("adjusted_points", s.adjustment.points)
      .Field("adjustment_initial_rmse_px", s.adjustment.initial_rmse_px)
      .Field("adjustment_final_rmse_px", s.adjustment.final_rmse_px)
      .Field("adjustment_culled_observations", s.adjustment.culled_observations)
      .Field("visibility_fit_rmse", s.visibility.final_rmse);
  if (session) {
    json.Key("session_localization")
        .BeginObject()
        .Field("frames", session->frames)
        .Field("localized_frames", session->localized_frames)
        .Field("paired_frames", session->paired_frames)
        .Field("agreeing_frames", session->agreeing_frames)
        .Field("position_rmse_m", session->position_rmse_m)
        .Field("seconds", session->localize_ms / 1e3)
        .EndObject();
  }
  if (update) {
    json.Field("checked_points", update->checked_points)
        .Field("removed_points", update->removed_points);
  }
  json.EndObject();
  return json.str();
}

void PrintHuman(const std::string& out, const Map& merged, const mapping::MergeStats& stats,
                const char* b_name, const mapping::SessionRegistrationStats* session = nullptr) {
  std::printf("%s: %zu keyframes (%d + %d), %zu points (%d fused, %d added from %s)\n", out.c_str(),
              merged.keyframes.size(), stats.keyframes_a, stats.keyframes_b, merged.points.size(),
              stats.fused_points, stats.added_points, b_name);
  if (session) {
    std::printf(
        "localized in the map: %d of %d images, %d agreeing on one placement of the "
        "session (camera centres within %.1f mm RMS), %.1f s\n",
        session->localized_frames, session->frames, session->agreeing_frames,
        session->position_rmse_m * 1e3, session->localize_ms / 1e3);
  }
  std::printf(
      "overlap: %d of %d %s agree on one alignment (RMSE %.1f mm); %s "
      "moved by %.3f m, turned %.2f deg\n",
      stats.inliers, stats.matches,
      stats.from_guess ? "point pairs near that placement" : "descriptor matches",
      stats.inlier_rmse_m * 1e3, b_name, stats.a_from_b.translation.norm(),
      RotationAngleDeg(stats.a_from_b.rotation));
  const mapping::MapAdjustmentStats& adjustment = stats.adjustment;
  if (adjustment.residual_blocks > 0) {
    std::printf(
        "bundle adjustment: %d keyframes and %d points adjusted (each point held near its "
        "stereo position), keyframes held: %d; reprojection RMSE %.2f -> %.2f px, %d "
        "observations culled, %.2f s\n",
        adjustment.free_keyframes, adjustment.points, adjustment.fixed_keyframes,
        adjustment.initial_rmse_px, adjustment.final_rmse_px, adjustment.culled_observations,
        adjustment.time_ms / 1e3);
  }
  std::printf("lineage: %s\n", merged.metadata.lineage.c_str());
}

// The progress line on stderr while a session is localized in the map, then mapped.
std::function<void(const mapping::SessionMergeProgress&)> ProgressLine(bool show) {
  if (!show) return nullptr;
  return [](const mapping::SessionMergeProgress& p) {
    if (p.stage == mapping::SessionMergeProgress::Stage::kLocalizing) {
      std::fprintf(stderr, "\r\33[Klocalizing in the map: %d / %d", p.done, p.total);
    } else {
      std::fprintf(stderr, "\r\33[Kframe %d / %d: %s", p.done, p.total, p.status.c_str());
    }
  };
}

// `map extend` and `map update`: the session in DIR merged into the map at `map_path` (by
// mapping::MergeSession), the file replaced atomically; stats for the report.
Map MergeDatasetSession(const std::string& map_path, const std::string& dataset_dir,
                        const std::string& format, mapping::SessionMergeKind kind,
                        const mapping::SessionMergeOptions& options, bool progress,
                        mapping::SessionMergeStats* stats) {
  const Map existing = mapstore::LoadMap(map_path);
  const Dataset dataset = ReadDataset(dataset_dir, ParseOptionalDatasetFormat(format));
  const mapping::DatasetSource session(dataset, dataset_dir);
  Map merged;
  try {
    merged = mapping::MergeSession(existing, session, kind, options, stats, ProgressLine(progress));
  } catch (...) {
    if (progress) std::fprintf(stderr, "\r\33[K");
    throw;
  }
  if (progress) std::fprintf(stderr, "\r\33[K");
  mapstore::SaveMap(merged, map_path);
  return merged;
}

// --threads for the session's mapping, every core unless given (as map build).
void AddThreadsFlag(ArgParser& parser, mapping::SessionMergeOptions* options) {
  options->threads = 0;
  parser.AddFlag("threads", &options->threads,
                 "threads for mapping the session (the same map for any count)");
  parser.SetDefaultText("threads", "0: every core");
}

void AddOverlapFlags(ArgParser& parser, mapping::MergeOptions* options) {
  parser.AddFlag("inlier-distance", &options->inlier_distance_m,
                 "metres within which matched points agree on the alignment (0.05)");
  parser.AddFlag("min-inliers", &options->min_inliers, "fewer agreeing matches: no overlap (40)");
  parser.AddSwitch("no-adjust", &options->skip_adjustment,
                   "skip the bundle adjustment of the new keyframes after the rigid alignment");
}

}  // namespace

int RunMapMerge(const Args& args) {
  std::string a_path, b_path, out, name;
  bool json = false;
  mapping::MergeOptions options;
  ArgParser parser(
      "visloc map merge",
      "Merges two maps of overlapping places into one, in the first map's frame: their points "
      "matched by descriptor, the overlap verified by a RANSAC rigid alignment of the matched "
      "3D points (stereo maps share metric scale), duplicates fused, the visibility kernel "
      "learned again and the vocabulary retrained. Maps without a verified overlap (different "
      "places) are refused with the evidence. The output is written atomically.");
  parser.AddPositional("A", &a_path, "the map whose frame the result keeps");
  parser.AddPositional("B", &b_path, "the map merged into it");
  parser.AddFlag("out", &out, "the merged map file to write", /*required=*/true);
  parser.AddFlag("name", &name, "the merged map's name (default: A's)");
  AddOverlapFlags(parser, &options);
  parser.AddSwitch("json", &json, "print the result as JSON");
  if (!parser.Parse(args, std::cout)) return 0;
  CheckFlags(options);
  const Map a = mapstore::LoadMap(a_path);
  const Map b = mapstore::LoadMap(b_path);
  mapping::MergeStats stats;
  Map merged = mapping::MergeMaps(a, b, options, &stats);
  if (!name.empty()) merged.metadata.name = name;
  mapstore::SaveMap(merged, out);
  if (json) {
    std::cout << ToJson(out, merged, stats) << "\n";
    return 0;
  }
  PrintHuman(out, merged, stats, "B");
  return 0;
}

int RunMapExtend(const Args& args) {
  std::string map_path, dataset_dir, format;
  bool json = false;
  mapping::SessionMergeOptions session_options;
  mapping::MergeOptions& options = session_options.update.merge;
  ArgParser parser(
      "visloc map extend",
      "Adds a new stereo session to a map, in the map's frame: its images are localized in the "
      "map as a robot's would be (relocalization, then tracking), the session is mapped on its "
      "own (as map build does, with the map's detector), the images placed both ways place it "
      "in the map, its points near the map's refine that placement, and it is merged: "
      "duplicates fused, old and new keyframes and points adjusted together, the visibility "
      "kernel learned again over all keyframes and the vocabulary retrained, so the new areas "
      "relocalize. A session that never localizes in the map is refused. The map file is "
      "replaced atomically when the extended map is complete.");
  parser.AddPositional("MAP", &map_path, "the map file to extend (replaced)");
  parser.AddFlag("dataset", &dataset_dir, "the new session: a stereo dataset folder", true);
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  AddOverlapFlags(parser, &options);
  AddThreadsFlag(parser, &session_options);
  parser.AddSwitch("json", &json, "print the result as JSON");
  if (!parser.Parse(args, std::cout)) return 0;
  CheckFlags(session_options);
  mapping::SessionMergeStats stats;
  const Map extended =
      MergeDatasetSession(map_path, dataset_dir, format, mapping::SessionMergeKind::kExtend,
                          session_options, ShowProgress() && !json, &stats);
  if (json) {
    std::cout << ToJson(map_path, extended, stats.update.merge, &stats.registration) << "\n";
  } else {
    PrintHuman(map_path, extended, stats.update.merge, "the session", &stats.registration);
  }
  return 0;
}

int RunMapUpdate(const Args& args) {
  std::string map_path, dataset_dir, format;
  bool json = false;
  mapping::SessionMergeOptions session_options;
  mapping::UpdateOptions& options = session_options.update;
  ArgParser parser(
      "visloc map update",
      "Brings a map up to date with a new stereo session through a place that changed: the "
      "session is mapped and localized in the map (as extend does); map points that several of its "
      "keyframes "
      "should have seen (in the image, in range, from a similar direction) and none did are "
      "removed; then the session is merged in, so what is new is added. Points the session never "
      "came near are kept. The map file is replaced atomically.");
  parser.AddPositional("MAP", &map_path, "the map file to update (replaced)");
  parser.AddFlag("dataset", &dataset_dir, "the new session: a stereo dataset folder", true);
  parser.AddFlag("format", &format, "euroc or kitti (default: detected)");
  parser.AddFlag("min-expected-views", &options.min_expected_views,
                 "session keyframes that must have expected a point before it can go (3)");
  AddOverlapFlags(parser, &options.merge);
  AddThreadsFlag(parser, &session_options);
  parser.AddSwitch("json", &json, "print the result as JSON");
  if (!parser.Parse(args, std::cout)) return 0;
  CheckFlags(session_options);
  mapping::SessionMergeStats stats;
  const Map updated =
      MergeDatasetSession(map_path, dataset_dir, format, mapping::SessionMergeKind::kUpdate,
                          session_options, ShowProgress() && !json, &stats);
  if (json) {
    std::cout << ToJson(map_path, updated, stats.update.merge, &stats.registration, &stats.update)
              << "\n";
  } else {
    std::printf("%s: %d of %d points checked against the session, %d gone and removed\n",
                map_path.c_str(), stats.update.checked_points, stats.map_points,
                stats.update.removed_points);
    PrintHuman(map_path, updated, stats.update.merge, "the session", &stats.registration);
  }
  return 0;
}

}  // namespace visloc::cli
