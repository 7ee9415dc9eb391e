// `visloc map align`: ties a map to its site's frame (mapping/site_alignment.h) and stores the
// transform in the map, the file replaced atomically.

#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "client/map_report.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"
#include "mapping/site_alignment.h"
#include "mapstore/map_store.h"

namespace visloc::cli {
namespace {

// PAIRS.csv: one pair a line, NAME,MAP_X,MAP_Y,MAP_Z,SITE_X,SITE_Y,SITE_Z (metres); '#' lines
// are skipped, and so is the first line when its coordinates are not numbers (a header).
std::vector<mapping::PositionPair> ReadPairs(const std::string& path) {
  std::vector<mapping::PositionPair> pairs;
  for (const TextLine& line : ReadTextLines(path)) {
    if (line.text.empty() || line.text[0] == '#') continue;
    const std::vector<std::string> fields = Split(line.text, ',');
    const auto where = StrCat(path, ":", line.number, ": ");
    if (fields.size() != 7) {
      throw InputError(StrCat(where, "expected NAME,MAP_X,MAP_Y,MAP_Z,SITE_X,SITE_Y,SITE_Z, found ",
                              fields.size(), " fields"));
    }
    double values[6];
    bool numeric = true;
    for (int i = 0; i < 6; ++i) {
      const auto value = ParseDouble(fields[i + 1]);
      numeric = numeric && value && std::isfinite(*value);
      if (numeric) values[i] = *value;
    }
    if (!numeric) {
      if (line.number == 1) continue;  // A header.
      throw InputError(StrCat(where, "the coordinates are not all finite numbers"));
    }
    pairs.push_back({fields[0].empty() ? StrCat("line ", line.number) : fields[0],
                     Eigen::Vector3d(values[0], values[1], values[2]),
                     Eigen::Vector3d(values[3], values[4], values[5])});
  }
  return pairs;
}

void PrintPairs(const std::vector<mapping::PositionPair>& pairs,
                const mapping::SiteAlignResult& result) {
  std::printf("%-24s %12s %18s\n", "pair", "residual, cm", "left out, cm");
  for (size_t i = 0; i < pairs.size() && i < result.residuals_m.size(); ++i) {
    std::printf("%-24s %12.2f %18.2f\n", pairs[i].name.c_str(), 100 * result.residuals_m[i],
                100 * result.left_out_residuals_m[i]);
  }
}

}  // namespace

int RunMapAlign(const Args& args) {
  std::string map_path, pairs_path, trajectory_path, reference_path;
  mapping::SiteAlignOptions options;
  bool json = false, dry_run = false;
  ArgParser parser(
      "visloc map align",
      "Ties a map to its site's frame: pairs of positions (a point in the map, the same point "
      "surveyed in the site), or a run's trajectory in the map beside a reference trajectory "
      "of the site with the same stamps. Solves the rigid transform, reports each pair's "
      "residual, refuses a pair that disagrees with the others, and stores the transform in "
      "the map: robots, ROS, the operator page and exports then speak the site frame.");
  parser.AddPositional("MAP", &map_path, "the map file");
  parser.AddFlag("pairs", &pairs_path,
                 "CSV: NAME,MAP_X,MAP_Y,MAP_Z,SITE_X,SITE_Y,SITE_Z per line (metres; a header "
                 "line and # comments allowed)");
  parser.AddFlag("trajectory", &trajectory_path,
                 "TUM: a run's poses in the map frame (visloc localize/stream --trajectory)");
  parser.AddFlag("reference", &reference_path,
                 "TUM: the same run in the site frame (motion capture, total station, RTK-GNSS)");
  parser.AddFlag("max-residual", &options.max_residual_m,
                 "metres: a pair farther than this from where the others put it is refused");
  parser.AddSwitch("dry-run", &dry_run, "fit and report, but leave the map as it is");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(args, std::cout)) return 0;
  if (map_path.empty()) throw UsageError("missing MAP");
  if (pairs_path.empty() == trajectory_path.empty()) {
    throw UsageError("give --pairs PAIRS.csv, or --trajectory EST.tum with --reference REF.tum");
  }
  if (!trajectory_path.empty() && reference_path.empty()) {
    throw UsageError("--trajectory needs --reference");
  }
  if (!(options.max_residual_m > 0)) throw UsageError("--max-residual must be positive");
  Map map = mapstore::LoadMap(map_path);
  const std::vector<mapping::PositionPair> pairs =
      pairs_path.empty()
          ? mapping::PairsFromTrajectories(ReadTum(trajectory_path), ReadTum(reference_path))
          : ReadPairs(pairs_path);
  const std::string reference =
      pairs_path.empty() ? StrCat("trajectory ", trajectory_path, " beside ", reference_path)
                         : StrCat("pairs ", pairs_path);
  const mapping::SiteAlignResult result =
      mapping::AlignToSite(pairs, map.metadata.gravity, reference, options);
  if (result.site && !dry_run) {
    map.metadata.site = result.site;
    mapstore::SaveMap(map, map_path);
  }
  if (json) {
    JsonWriter out;
    out.BeginObject()
        .Field("map", map_path)
        .Field("aligned", result.site.has_value())
        .Field("stored", result.site.has_value() && !dry_run)
        .Field("pairs", static_cast<int64_t>(pairs.size()));
    if (result.site) {
      out.Field("rms_m", result.site->rms_m).Field("max_residual_m", result.site->max_residual_m);
      WritePoseField(out, "site_from_map", result.site->site_from_map);
    } else {
      out.Field("problem", result.why_not);
    }
    if (result.site_z_from_up_deg) out.Field("site_z_from_up_deg", *result.site_z_from_up_deg);
    out.Key("residuals").BeginArray();
    for (size_t i = 0; i < result.residuals_m.size(); ++i) {
      out.BeginObject()
          .Field("name", pairs[i].name)
          .Field("residual_m", result.residuals_m[i])
          .Field("left_out_residual_m", result.left_out_residuals_m[i])
          .EndObject();
    }
    out.EndArray().EndObject();
    std::cout << out.str() << "\n";
  } else {
    if (!result.residuals_m.empty()) PrintPairs(pairs, result);
    if (result.site) {
      std::printf("%s: tied to %s by %d pairs, residual %.2f cm rms, %.2f cm at most%s\n",
                  map_path.c_str(), reference.c_str(), result.site->pairs, 100 * result.site->rms_m,
                  100 * result.site->max_residual_m, dry_run ? " (dry run: not stored)" : "");
      if (result.site_z_from_up_deg) {
        std::printf("the site's z is %.2f deg from the map's up\n", *result.site_z_from_up_deg);
      }
    }
  }
  if (!result.site) throw InputError("cannot tie the map to the site: " + result.why_not);
  return 0;
}

}  // namespace visloc::cli
