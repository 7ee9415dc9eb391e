#include "server/map_cache.h"

#include <gtest/gtest.h>

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
