#include "server/localizability_cache.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"

namespace visloc::server {
namespace {

using std::chrono::seconds;

// A small map whose up is recorded (y down: its cameras were level), so it has a level frame.
void SaveLevelMap(const std::string& path) {
  SyntheticMapOptions options;
  options.keyframes = 10;
  options.points = 300;
  Map map = MakeSyntheticMap(options);
  map.metadata.gravity = MapGravity{-Eigen::Vector3d::UnitY(), 0.5, MapGravity::Source::kLevelRig};
  mapstore::SaveMap(map, path);
}

LocalizabilityGrid OneCellGrid() {
  LocalizabilityGrid grid;
  grid.cells_x = grid.cells_y = 1;
  grid.headings = 1;
  LocalizabilityEstimate estimate;
  estimate.expected_inliers = 40.0f;
  estimate.position_sigma_m = 0.01f;
  estimate.good = true;
  grid.estimates.assign(1, estimate);
  return grid;
}

// Bug: the cache held one lock while computing, so the page's grid for a small map waited
// behind a 10,000-keyframe map's (minutes under a sanitizer) and never came.
TEST(LocalizabilityCacheTest, AGridOfOneMapNeverWaitsBehindAnothersComputation) {
  TempDir dir;
  SaveLevelMap(dir.File("big.db"));
  SaveLevelMap(dir.File("small.db"));
  MapCache maps(dir.path(), seconds(60));
  std::promise<void> release_big;
  std::shared_future<void> big_released = release_big.get_future().share();
  std::atomic<int> computed{0};
  LocalizabilityCache cache(&maps, 250'000, 1,
                            [&](const LocalizationMap& map, const Rigid3d&,
                                const LocalizabilityOptions&, LocalizabilityStats*) {
                              ++computed;
                              if (&map == maps.Acquire("big").get()) {
                                big_released.wait();
                              }
                              return OneCellGrid();
                            });
  auto big = std::async(std::launch::async, [&] { return cache.Get("big", {}); });
  while (computed.load() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  auto small = std::async(std::launch::async, [&] { return cache.Get("small", {}); });
  const bool small_answered = small.wait_for(seconds(20)) == std::future_status::ready;
  release_big.set_value();
  EXPECT_TRUE(small_answered) << "the small map's grid waited for the big map's";
  EXPECT_EQ(small.get()->map, "small");
  EXPECT_EQ(big.get()->map, "big");
  EXPECT_EQ(computed.load(), 2);
}

TEST(LocalizabilityCacheTest, CallersOfAGridBeingComputedShareThatOneComputation) {
  TempDir dir;
  SaveLevelMap(dir.File("lab.db"));
  MapCache maps(dir.path(), seconds(60));
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> computed{0};
  LocalizabilityCache cache(&maps, 250'000, 1,
                            [&](const LocalizationMap&, const Rigid3d&,
                                const LocalizabilityOptions&, LocalizabilityStats* stats) {
                              ++computed;
                              released.wait();
                              stats->seconds = 1.5;
                              return OneCellGrid();
                            });
  std::vector<std::future<std::shared_ptr<const LocalizabilityReport>>> callers;
  for (int i = 0; i < 4; ++i) {
    callers.push_back(std::async(std::launch::async, [&] { return cache.Get("lab", {}); }));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  release.set_value();
  int computed_here = 0;
  for (auto& caller : callers) {
    const auto report = caller.get();
    ASSERT_EQ(report->grid.estimates.size(), 1u);
    EXPECT_EQ(report->grid.estimates[0].expected_inliers, 40.0f);
    computed_here += report->stats.seconds > 0.0;  // Only the computing caller reports time.
  }
  EXPECT_EQ(computed.load(), 1);
  EXPECT_EQ(computed_here, 1);
  // Other grid options are another grid.
  LocalizabilityRequest coarse;
  coarse.cell_m = 2.0;
  cache.Get("lab", coarse);
  EXPECT_EQ(computed.load(), 2);
}

TEST(LocalizabilityCacheTest, AGridLastsWhileItsMapStaysLoadedAndAReplacedMapGetsANewOne) {
  TempDir dir;
  SaveLevelMap(dir.File("lab.db"));
  MapCache maps(dir.path(), seconds(60));
  int computed = 0;
  LocalizabilityCache cache(&maps, 250'000, 1,
                            [&](const LocalizationMap&, const Rigid3d&,
                                const LocalizabilityOptions&, LocalizabilityStats* stats) {
                              ++computed;
                              stats->seconds = 1.0;
                              return OneCellGrid();
                            });
  EXPECT_EQ(cache.Get("lab", {})->stats.seconds, 1.0);
  // No caller holds the map between the page's clicks: the grid is kept all the same.
  EXPECT_EQ(cache.Get("lab", {})->stats.seconds, 0.0);
  EXPECT_EQ(computed, 1);
  SaveLevelMap(dir.File("lab.db"));  // An upload replaces the file: a new map.
  EXPECT_EQ(cache.Get("lab", {})->stats.seconds, 1.0);
  EXPECT_EQ(computed, 2);
}

TEST(LocalizabilityCacheTest, AMapWithoutUpIsRefusedByNameAndEveryCallerGetsTheReason) {
  TempDir dir;
  SaveLevelMap(dir.File("lab.db"));
  MapCache maps(dir.path(), seconds(60));
  int computed = 0;
  LocalizabilityCache cache(
      &maps, 250'000, 1,
      [&](const LocalizationMap&, const Rigid3d&, const LocalizabilityOptions&,
          LocalizabilityStats*) {
        ++computed;
        throw InputError("localizability of 9,000,000 poses: at most 250,000");
        return LocalizabilityGrid{};
      });
  for (int i = 0; i < 2; ++i) {
    try {
      cache.Get("lab", {});
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("at most 250,000"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(computed, 1);
  LocalizabilityRequest bad;
  bad.headings = 0;
  EXPECT_THROW(cache.Get("lab", bad), InputError);
  EXPECT_THROW(cache.Get("nowhere", {}), NotFoundError);
}

}  // namespace
}  // namespace visloc::server
