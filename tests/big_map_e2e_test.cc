// A map larger than the server's memory bound, served paged: the fixture's map tiled into
// twelve copies (tile_map), visloc-server with --map-memory-mib well below the map's size, and
// the real `visloc stream` client through a kidnapping. The answers are those of the same map
// served whole; the server's log shows the pages it read.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

#include "core/util/temp_dir.h"
#include "tests/support/e2e.h"
#include "tests/support/process.h"

namespace visloc {
namespace {

using ::testing::HasSubstr;
using testing::JsonNumber;
using testing::ProcessResult;
using testing::RunProcess;
using testing::ServerProcess;
using testing::Visloc;

const std::string kData = VISLOC_LOCALIZATION_DATA;

// A session_end field of the server's log, as a number (NaN when absent).
double LogField(const std::string& log, const std::string& field) {
  std::smatch match;
  if (!std::regex_search(log, match, std::regex("event=session_end.* " + field + "=([0-9.]+)")))
    return NAN;
  return std::stod(match[1]);
}

class BigMapE2eTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const ProcessResult tiled =
        RunProcess({VISLOC_TILE_MAP_PATH, kData + "/map.db", maps_.File("big.db"), "12", "30"});
    ASSERT_EQ(tiled.exit_code, 0) << tiled.err;
    const ProcessResult info = Visloc({"map", "info", maps_.File("big.db"), "--json"});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    map_mib_ = JsonNumber(info.out, "memory_bytes") / (1 << 20);
  }
  ProcessResult StreamKidnap(const ServerProcess& server) {
    return Visloc({"stream", "--server", server.address(), "--map", "big", "--dataset",
                   kData + "/kidnap", "--rate", "0", "--gt", kData + "/kidnap/groundtruth_map.tum",
                   "--trajectory", out_.File("est.tum"), "--json"});
  }
  TempDir maps_{"visloc_big_maps"};
  TempDir out_{"visloc_big_out"};
  double map_mib_ = 0;
};

TEST_F(BigMapE2eTest, AMapFiveTimesTheBoundIsServedPagedWithTheWholeMapsAnswers) {
  ASSERT_GT(map_mib_, 25);  // Twelve copies of a 2.4 MB map.
  ServerProcess whole(VISLOC_SERVER_PATH, maps_.path());
  const ProcessResult reference = StreamKidnap(whole);
  ASSERT_EQ(reference.exit_code, 0) << reference.err;
  whole.Stop();

  ServerProcess bounded(VISLOC_SERVER_PATH, maps_.path(), {"--map-memory-mib", "5"});
  const ProcessResult paged = StreamKidnap(bounded);
  ASSERT_EQ(paged.exit_code, 0) << paged.err;
  EXPECT_EQ(JsonNumber(paged.out, "errors"), 0);
  EXPECT_EQ(JsonNumber(paged.out, "frames"), 150);
  // Tracking, losing the robot while it is carried, and finding it again among twelve copies
  // that look alike (copy 0, where the ground truth is) all go as with the whole map.
  EXPECT_NEAR(JsonNumber(paged.out, "localized_fraction"), 132.0 / 150, 0.01);
  EXPECT_EQ(JsonNumber(paged.out, "localized_fraction"),
            JsonNumber(reference.out, "localized_fraction"));
  EXPECT_LT(JsonNumber(paged.out, "position_max_m"), 0.05);
  EXPECT_NEAR(JsonNumber(paged.out, "position_median_m"),
              JsonNumber(reference.out, "position_median_m"), 1e-4);
  bounded.Stop();
  const std::string log = bounded.Log();
  EXPECT_GT(LogField(log, "map_page_loads"), 0) << log;
  EXPECT_GT(LogField(log, "map_page_hits"), LogField(log, "map_page_loads"));
  EXPECT_LE(LogField(log, "map_memory_mib"), 5.0);
  EXPECT_LT(LogField(log, "map_pages_peak_live_mib"), 5.0);
}

TEST_F(BigMapE2eTest, ABoundTooSmallForTheResidentIndexIsRefusedByName) {
  ServerProcess bounded(VISLOC_SERVER_PATH, maps_.path(), {"--map-memory-mib", "3"});
  const ProcessResult refused = StreamKidnap(bounded);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_THAT(refused.err, HasSubstr("MiB of keyframes, kernel and appearance index resident"));
  EXPECT_THAT(refused.err, HasSubstr("more than the server's --map-memory-mib of 3"));
  // A bound that is no bound is refused at start.
  const ProcessResult negative = RunProcess(
      {VISLOC_SERVER_PATH, "--maps", maps_.path(), "--map-memory-mib", "-1"});
  EXPECT_NE(negative.exit_code, 0);
  EXPECT_THAT(negative.err, HasSubstr("--map-memory-mib must be 0 (no bound) to 16777216"));
  // The server keeps serving: a session on a map within the bound (loaded whole) works.
  std::filesystem::copy_file(kData + "/map.db", maps_.File("square.db"));
  const ProcessResult other =
      Visloc({"stream", "--server", bounded.address(), "--map", "square", "--dataset",
              kData + "/kidnap", "--rate", "0", "--frames", "20", "--json"});
  EXPECT_EQ(other.exit_code, 0) << other.err;
  EXPECT_EQ(JsonNumber(other.out, "frames"), 20);
}

}  // namespace
}  // namespace visloc
