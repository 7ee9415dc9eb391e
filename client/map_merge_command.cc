// `visloc map merge A.db B.db --out C.db`: two maps of overlapping places into one, in A's frame
// (mapping/map_merge.h). Maps with no verified overlap are refused with the evidence.

#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "mapping/map_merge.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

std::string ToJson(const std::string& out, const Map& merged, const mapping::MergeStats& s) {
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
      .Field("visibility_fit_rmse", s.visibility.final_rmse)
      .EndObject();
  return json.str();
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
  parser.AddFlag("inlier-distance", &options.inlier_distance_m,
                 "metres within which matched points agree on the alignment (0.05)");
  parser.AddFlag("min-inliers", &options.min_inliers, "fewer agreeing matches: no overlap (40)");
  parser.AddSwitch("json", &json, "print the result as JSON");
  if (!parser.Parse(args, std::cout)) return 0;
  if (const std::string problem = options.Problem(); !problem.empty()) throw UsageError(problem);
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
  std::printf("%s: %zu keyframes (%d + %d), %zu points (%d fused, %d added from B)\n", out.c_str(),
              merged.keyframes.size(), stats.keyframes_a, stats.keyframes_b, merged.points.size(),
              stats.fused_points, stats.added_points);
  std::printf("overlap: %d of %d descriptor matches agree on one alignment (RMSE %.1f mm); B "
              "moved by %.3f m, turned %.2f deg\n",
              stats.inliers, stats.matches, stats.inlier_rmse_m * 1e3,
              stats.a_from_b.translation.norm(), RotationAngleDeg(stats.a_from_b.rotation));
  std::printf("lineage: %s\n", merged.metadata.lineage.c_str());
  return 0;
}

}  // namespace visloc::cli
