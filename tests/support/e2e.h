#pragma once
// Helpers shared by the end-to-end tests: run the `visloc` binary under test, read numbers out
// of its --json output, write the shared small map. Header-only because VISLOC_CLI_PATH is defined
// per test target (tests/CMakeLists.txt, visloc_add_e2e_test).

#include <gtest/gtest.h>

#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/map/synthetic_map.h"
#include "dataset/tum.h"
#include "mapstore/map_store.h"
#include "tests/support/process.h"

namespace visloc::testing {

// Runs `visloc ARGS...` and captures its exit code and output.
inline ProcessResult Visloc(std::vector<std::string> args) {
  args.insert(args.begin(), VISLOC_CLI_PATH);
  return RunProcess(args);
}

// The number after "key": in `json`, searching from the first occurrence of "section" (from the
// start when `section` is empty). A missing key fails the test and returns -1.
inline double JsonNumber(const std::string& json, const std::string& section,
                         const std::string& key) {
  const size_t from = section.empty() ? 0 : json.find("\"" + section + "\"");
  const size_t at = from == std::string::npos ? from : json.find("\"" + key + "\":", from);
  if (at == std::string::npos) {
    ADD_FAILURE() << "no " << section << (section.empty() ? "" : ".") << key << " in " << json;
    return -1;
  }
  return std::stod(json.substr(at + key.size() + 3));
}

inline double JsonNumber(const std::string& json, const std::string& key) {
  return JsonNumber(json, "", key);
}

// How far `trajectory` drifts from the ground truth `truth_tum` (both TUM, the map frame):
// {the median error as a share of the distance travelled, the last pose's error as a share of
// the whole path}. `scratch_tum` receives the trajectory's first and last poses.
inline std::pair<double, double> DriftShares(const std::string& truth_tum,
                                             const std::string& trajectory,
                                             const std::string& scratch_tum) {
  const ProcessResult all = Visloc({"eval", "--gt", truth_tum, "--est", trajectory, "--json"});
  EXPECT_EQ(all.exit_code, 0) << all.err;
  const Trajectory poses = ReadTum(trajectory);
  EXPECT_FALSE(poses.empty()) << trajectory;
  if (poses.empty()) return {-1, -1};
  WriteTum(scratch_tum, {poses.front(), poses.back()});
  const ProcessResult end = Visloc({"eval", "--gt", truth_tum, "--est", scratch_tum, "--json"});
  EXPECT_EQ(end.exit_code, 0) << end.err;
  return {JsonNumber(all.out, "ate_per_distance", "median"),
          JsonNumber(end.out, "ate_per_distance", "max")};
}

// The poses of a TUM file whose times may repeat (`visloc map export --keyframes` of a map that
// holds two sessions of the same times), in file order; ReadTum insists on increasing times.
inline Trajectory ReadTumLines(const std::string& path) {
  Trajectory poses;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string stamp;
    double x, y, z, qx, qy, qz, qw;
    fields >> stamp >> x >> y >> z >> qx >> qy >> qz >> qw;
    // To the nanosecond, as written: through a double, a stamp of 1.7e9 s is 100 ns off, and
    // matching it to ground truth then falls back to interpolation.
    const std::optional<int64_t> t_ns = ParseSecondsToNs(stamp);
    if (!t_ns) throw std::runtime_error("bad TUM timestamp '" + stamp + "' in " + path);
    poses.push_back({*t_ns, Rigid3d(Eigen::Quaterniond(qw, qx, qy, qz), {x, y, z})});
  }
  return poses;
}

// The complete pose lines (newline-terminated, not the '#' header) of a TUM file that a running
// `visloc stream --trajectory` may be writing: how many poses the robot has had so far.
inline int PosesWrittenTo(const std::string& tum_path) {
  std::ifstream in(tum_path);
  std::string line;
  int poses = 0;
  while (std::getline(in, line)) poses += !in.eof() && !line.empty() && line[0] != '#';
  return poses;
}

// Writes the small synthetic map the map-management and fault tests share: "lab", 20 keyframes,
// 2,000 points (about 0.5 MB). The test target links visloc::mapstore and visloc::map.
inline void SaveLabMap(const std::string& path) {
  SyntheticMapOptions options;
  options.keyframes = 20;
  options.points = 2000;
  options.name = "lab";
  mapstore::SaveMap(MakeSyntheticMap(options), path);
}

}  // namespace visloc::testing
