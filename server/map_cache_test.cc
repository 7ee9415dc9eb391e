#include "server/map_cache.h"

#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <thread>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"

namespace visloc::server {
namespace {

Map SmallMap(int points) {
  SyntheticMapOptions options;
  options.keyframes = 10;
  options.points = points;
  return MakeSyntheticMap(options);
}

TEST(MapCacheTest, LoadsOnceSharesAndPicksUpReplacedFiles) {
  TempDir dir;
  mapstore::SaveMap(SmallMap(200), dir.File("lab.db"));
  MapCache cache(dir.path(), std::chrono::seconds(0));
  const auto first = cache.Acquire("lab");
  EXPECT_EQ(cache.Acquire("lab"), first);
  EXPECT_EQ(cache.stats().loads, 1);
  EXPECT_EQ(cache.stats().hits, 1);
  // Replaced on disk: new sessions get the new map, the old one stays valid for its holders.
  mapstore::SaveMap(SmallMap(300), dir.File("lab.db"));
  const auto second = cache.Acquire("lab");
  EXPECT_NE(second, first);
  EXPECT_EQ(second->point_count(), 300u);
  EXPECT_EQ(first->point_count(), 200u);
}

TEST(MapCacheTest, SessionsRacingForANewMapLoadItOnce) {
  TempDir dir;
  mapstore::SaveMap(SmallMap(20000), dir.File("big.db"));
  MapCache cache(dir.path(), std::chrono::seconds(60));
  std::vector<std::thread> sessions;
  std::vector<std::shared_ptr<const LocalizationMap>> got(6);
  for (int i = 0; i < 6; ++i) {
    sessions.emplace_back([&, i] { got[i] = cache.Acquire("big"); });
  }
  for (auto& t : sessions) t.join();
  EXPECT_EQ(cache.stats().loads, 1);
  for (const auto& map : got) EXPECT_EQ(map.get(), got[0].get());
}

// Sessions on a map larger than the bound read its pages at once, through one small cache that
// evicts while they read; every one reads what the whole map holds (and ThreadSanitizer, which
// runs this test in CI, sees the page cache and the file's pages under races).
TEST(MapCacheTest, RacingSessionsOnAPagedMapReadWhatTheWholeMapHolds) {
  TempDir dir;
  const Map whole = SmallMap(20000);
  mapstore::SaveMap(whole, dir.File("big.db"));
  MapCache cache(dir.path(), std::chrono::seconds(60), 2 << 20);
  const auto map = cache.Acquire("big");
  ASSERT_TRUE(map->paged());
  EXPECT_EQ(cache.stats().paged_loads, 1);
  std::vector<std::vector<Eigen::Vector3d>> seen_by(whole.keyframes.size());
  for (const Observation& o : whole.observations) {
    seen_by[o.keyframe].push_back(whole.points[o.point].position_in_map);
  }
  std::atomic<int> mismatches{0};
  std::vector<std::thread> sessions;
  for (int s = 0; s < 4; ++s) {
    sessions.emplace_back([&, s] {
      for (int round = 0; round < 3; ++round) {
        for (size_t i = 0; i < whole.keyframes.size(); ++i) {
          const size_t k = (i * (s + 1) + round) % whole.keyframes.size();
          const auto visible = map->VisiblePoints(k);
          const std::vector<uint32_t> ids(visible.begin(), visible.end());
          const PointView points = map->Points(ids);
          for (size_t j = 0; j < ids.size(); ++j) {
            if (j >= seen_by[k].size() || points.position(ids[j]) != seen_by[k][j]) ++mismatches;
          }
        }
      }
    });
  }
  for (auto& t : sessions) t.join();
  EXPECT_EQ(mismatches, 0);
  const PageCacheStats pages = map->page_stats();
  EXPECT_GT(pages.evictions, 0u);
  EXPECT_LE(pages.cached_bytes, pages.budget_bytes);
  EXPECT_LE(map->MemoryBytes(), size_t{2} << 20);
}

TEST(MapCacheTest, UnloadsOnlyMapsNoSessionHolds) {
  TempDir dir;
  mapstore::SaveMap(SmallMap(100), dir.File("a.db"));
  mapstore::SaveMap(SmallMap(100), dir.File("b.db"));
  MapCache cache(dir.path(), std::chrono::seconds(0));
  auto held = cache.Acquire("a");
  cache.Acquire("b");
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(cache.UnloadIdle(), 1);
  EXPECT_EQ(cache.loaded(), 1);
  held.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(cache.UnloadIdle(), 1);
  EXPECT_EQ(cache.loaded(), 0);
}

TEST(MapCacheTest, CountsTheUsersOfAMapAcrossItsVersions) {
  TempDir dir;
  mapstore::SaveMap(SmallMap(100), dir.File("lab.db"));
  MapCache cache(dir.path(), std::chrono::seconds(0));
  EXPECT_EQ(cache.UsersOf("lab"), 0);
  auto first = cache.Acquire("lab");
  auto second = cache.Acquire("lab");
  EXPECT_EQ(cache.UsersOf("lab"), 2);
  mapstore::SaveMap(SmallMap(150), dir.File("lab.db"));  // Replaced: a third user, new version.
  auto third = cache.Acquire("lab");
  EXPECT_EQ(cache.UsersOf("lab"), 3);
  EXPECT_EQ(cache.UsersOf("other"), 0);
  first.reset();
  third.reset();
  EXPECT_EQ(cache.UsersOf("lab"), 1);
  second.reset();
  EXPECT_EQ(cache.UsersOf("lab"), 0);
  // A session may outlive the cache (a server shutting down): its lease still lets go safely.
  std::shared_ptr<const LocalizationMap> late;
  {
    MapCache gone(dir.path(), std::chrono::seconds(0));
    late = gone.Acquire("lab");
  }
  EXPECT_EQ(late->point_count(), 150u);
  late.reset();
}

TEST(MapCacheTest, UnknownBrokenAndEscapingNamesAreRefusedClearly) {
  TempDir dir;
  MapCache cache(dir.path(), std::chrono::seconds(60));
  try {
    cache.Acquire("nope");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "no map named 'nope' in the server's maps folder");
  }
  EXPECT_THROW(cache.Acquire("../etc/passwd"), InputError);
  { std::ofstream(dir.File("broken.db")) << "not a map"; }
  EXPECT_THROW(cache.Acquire("broken"), InputError);
}

}  // namespace
}  // namespace visloc::server
