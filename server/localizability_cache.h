#pragma once
// Localizability grids (core/localization/localizability.h) of the maps a server holds, for the
// GetLocalizability RPC and the operator's page. A grid costs seconds for a large map: it is
// computed once per loaded map and grid options, one computation at a time, and kept while its
// map stays loaded (a map replaced on disk is a new map, and gets a new grid).

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "proto/map_info_convert.h"
#include "server/map_cache.h"

namespace visloc::server {

struct LocalizabilityRequest {
  double cell_m = 0.5;
  int headings = 16;
  std::optional<double> height_m;
  std::optional<double> pitch_deg;
  bool operator==(const LocalizabilityRequest& o) const {
    return cell_m == o.cell_m && headings == o.headings && height_m == o.height_m &&
           pitch_deg == o.pitch_deg;
  }
};

class LocalizabilityCache {
 public:
  // At most `max_poses` cells times headings a grid (larger requests are refused by name), on
  // `threads` threads. `maps` must outlive the cache.
  LocalizabilityCache(MapCache* maps, int max_poses, int threads);

  // The grid of map NAME. Throws NotFoundError / InputError as MapCache::Acquire does, and
  // InputError for a request out of range or a map with no level frame (the reason).
  std::shared_ptr<const LocalizabilityReport> Get(const std::string& name,
                                                  const LocalizabilityRequest& request);

 private:
  struct Entry {
    std::string name;
    LocalizabilityRequest request;
    std::weak_ptr<const LocalizationMap> map;
    std::shared_ptr<const LocalizabilityReport> answer;
  };
  static constexpr size_t kMaxEntries = 16;

  MapCache* maps_;
  int max_poses_;
  int threads_;
  std::mutex mutex_;            // Held while computing: one grid at a time.
  std::vector<Entry> entries_;  // Most recent last.
};

}  // namespace visloc::server
