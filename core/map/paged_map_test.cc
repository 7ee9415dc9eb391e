#include <gtest/gtest.h>

#include <atomic>
#include <numeric>

#include "core/map/localization_map.h"
#include "core/map/page_cache.h"
#include "core/map/synthetic_map.h"
#include "core/util/check.h"

namespace visloc {
namespace {

std::shared_ptr<const void> Page(size_t bytes_value, size_t* bytes) {
  *bytes = bytes_value;
  return std::make_shared<const int>(static_cast<int>(bytes_value));
}

TEST(PageCacheTest, EvictsTheLeastRecentlyUsedPagesBeyondTheBudget) {
  PageCache cache(300);
  int loads = 0;
  auto get = [&](uint64_t key) {
    return cache.Get(key, [&](size_t* bytes) {
      ++loads;
      return Page(100, bytes);
    });
  };
  get(1);
  get(2);
  get(3);
  get(1);  // Hit: 1 is now the most recent, 2 the least.
  get(4);  // Over budget: 2 goes.
  EXPECT_EQ(loads, 4);
  get(1);
  get(3);
  EXPECT_EQ(loads, 4);
  get(2);  // Was evicted: loaded again.
  EXPECT_EQ(loads, 5);
  const PageCacheStats stats = cache.stats();
  EXPECT_EQ(stats.loads, 5u);
  EXPECT_EQ(stats.hits, 3u);
  EXPECT_EQ(stats.evictions, 2u);
  EXPECT_EQ(stats.cached_bytes, 300u);
  EXPECT_EQ(stats.peak_cached_bytes, 300u);
  EXPECT_EQ(stats.live_bytes, 300u);
}

TEST(PageCacheTest, APinnedPageOutlivesItsEvictionAndCountsAsLiveUntilReleased) {
  PageCache cache(100);
  std::shared_ptr<const void> pinned = cache.Get(1, [](size_t* bytes) { return Page(100, bytes); });
  cache.Get(2, [](size_t* bytes) { return Page(100, bytes); });  // Evicts 1 from the cache.
  EXPECT_EQ(cache.stats().cached_bytes, 100u);
  EXPECT_EQ(cache.stats().live_bytes, 200u);  // 1 is still held here.
  EXPECT_EQ(*static_cast<const int*>(pinned.get()), 100);
  pinned.reset();
  EXPECT_EQ(cache.stats().live_bytes, 100u);
  EXPECT_EQ(cache.stats().peak_live_bytes, 200u);
}

TEST(PageCacheTest, AFailedLoadCachesNothing) {
  PageCache cache(100);
  EXPECT_THROW(
      cache.Get(1, [](size_t*) -> std::shared_ptr<const void> { throw InputError("bad page"); }),
      InputError);
  EXPECT_EQ(cache.stats().loads, 0u);
  EXPECT_EQ(cache.stats().live_bytes, 0u);
}

// The paged half of a map, served from memory: what mapstore does from the file.
class MemorySource : public MapPageSource {
 public:
  MemorySource(const Map& map, uint32_t chunk_points) : map_(map), chunk_points_(chunk_points) {}
  uint32_t point_count() const override { return static_cast<uint32_t>(map_.points.size()); }
  uint32_t chunk_points() const override { return chunk_points_; }
  PointChunk LoadPointChunk(uint32_t chunk) const override {
    ++chunk_loads;
    PointChunk out;
    out.first = chunk * chunk_points_;
    const uint32_t end = std::min<uint32_t>(out.first + chunk_points_, point_count());
    out.points.assign(map_.points.begin() + out.first, map_.points.begin() + end);
    out.descriptors =
        map_.descriptors.rowRange(static_cast<int>(out.first), static_cast<int>(end)).clone();
    return out;
  }
  std::vector<uint32_t> LoadVisiblePoints(uint32_t keyframe) const override {
    std::vector<uint32_t> ids;
    for (const Observation& o : map_.observations) {
      if (o.keyframe == keyframe) ids.push_back(o.point);
    }
    return ids;
  }
  size_t BulkBytes() const override { return LocalizationMap::MemoryBytesFor(map_); }
  mutable std::atomic<int> chunk_loads{0};

 private:
  Map map_;
  uint32_t chunk_points_;
};

Map Skeleton(Map map) {
  map.points.clear();
  map.descriptors = cv::Mat(0, map.descriptors.cols, map.descriptors.type());
  map.observations.clear();
  return map;
}

// MakeSyntheticMap numbers its points at random along the loop; the mapper numbers them as it
// makes them, along the trajectory. Renumbered so, by the first keyframe that sees each.
Map InTrajectoryOrder(const Map& map) {
  std::vector<uint32_t> first_seen(map.points.size(), UINT32_MAX);
  for (const Observation& o : map.observations)
    first_seen[o.point] = std::min(first_seen[o.point], o.keyframe);
  std::vector<uint32_t> order(map.points.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return first_seen[a] < first_seen[b]; });
  std::vector<uint32_t> new_id(map.points.size());
  Map out = map;
  for (size_t i = 0; i < order.size(); ++i) {
    new_id[order[i]] = static_cast<uint32_t>(i);
    out.points[i] = map.points[order[i]];
    map.descriptors.row(static_cast<int>(order[i]))
        .copyTo(out.descriptors.row(static_cast<int>(i)));
  }
  for (Observation& o : out.observations) o.point = new_id[o.point];
  std::sort(out.observations.begin(), out.observations.end(),
            [](const Observation& a, const Observation& b) {
              return a.keyframe != b.keyframe ? a.keyframe < b.keyframe : a.point < b.point;
            });
  return out;
}

TEST(PagedMapTest, ReadsTheSamePointsAndVisibilityAsTheResidentMap) {
  SyntheticMapOptions options;
  options.keyframes = 60;
  options.points = 5000;
  const Map map = InTrajectoryOrder(MakeSyntheticMap(options));
  ASSERT_TRUE(FindMapProblems(map).empty()) << FindMapProblems(map).front();
  const LocalizationMap resident(map);
  auto source = std::make_shared<MemorySource>(map, 128);
  // A budget of a tenth of the points' bytes.
  const size_t budget = map.points.size() * (sizeof(MapPoint) + 64) / 10;
  const LocalizationMap paged(Skeleton(map), source, budget);
  EXPECT_TRUE(paged.paged());
  EXPECT_EQ(paged.point_count(), resident.point_count());
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    const auto a = resident.VisiblePoints(k), b = paged.VisiblePoints(k);
    ASSERT_EQ(std::vector<uint32_t>(a.begin(), a.end()), std::vector<uint32_t>(b.begin(), b.end()));
    const std::vector<uint32_t> ids(b.begin(), b.end());
    const PointView from_pages = paged.Points(ids), from_memory = resident.Points(ids);
    for (uint32_t id : ids) {
      ASSERT_EQ(from_pages.position(id), from_memory.position(id));
      int row_a = 0, row_b = 0;
      const cv::Mat& da = from_memory.descriptors(id, &row_a);
      const cv::Mat& db = from_pages.descriptors(id, &row_b);
      ASSERT_EQ(cv::norm(da.row(row_a), db.row(row_b), cv::NORM_L1), 0.0);
    }
  }
  const PageCacheStats stats = paged.page_stats();
  EXPECT_LE(stats.cached_bytes, budget);
  EXPECT_GT(stats.evictions, 0u);
  // Live: the cache plus at most one keyframe's pinned chunks (the views above were released).
  EXPECT_LE(stats.live_bytes, budget);
  EXPECT_LT(stats.peak_live_bytes, 2 * budget);
}

TEST(PagedMapTest, APointOutsideTheViewAndTheWholeMapBaselinesAreRefused) {
  SyntheticMapOptions options;
  options.keyframes = 20;
  options.points = 2000;
  const Map map = MakeSyntheticMap(options);
  const LocalizationMap paged(Skeleton(map), std::make_shared<MemorySource>(map, 256), 1 << 20);
  const PointView view = paged.Points({3, 4});
  EXPECT_NO_THROW(view.position(4));
  EXPECT_THROW(view.position(1999), CheckError);
  EXPECT_THROW(paged.AllPoints(), CheckError);
}

}  // namespace
}  // namespace visloc
