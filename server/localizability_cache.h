#pragma once
// Localizability grids (core/localization/localizability.h) of the maps a server holds, for the
// GetLocalizability RPC and the operator's page. A grid costs seconds for a large map (minutes
// for a 10,000-keyframe one under a sanitizer): it is computed once per loaded map and grid
// options, and kept while its map stays loaded (a map replaced on disk is a new map, and gets a
// new grid). Callers asking for a grid being computed wait for that computation; a grid of one
// map never waits behind another map's.

#include <functional>
#include <future>
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
  // How a grid is computed: ComputeLocalizability, replaced in tests.
  using ComputeFn = std::function<LocalizabilityGrid(
      const LocalizationMap&, const Rigid3d&, const LocalizabilityOptions&, LocalizabilityStats*)>;

  // At most `max_poses` cells times headings a grid (larger requests are refused by name), each
  // on `threads` threads. `maps` must outlive the cache.
  LocalizabilityCache(MapCache* maps, int max_poses, int threads, ComputeFn compute = {});

  // The grid of map NAME. Throws NotFoundError / InputError as MapCache::Acquire does, and
  // InputError for a request out of range or a map with no level frame (the reason).
  std::shared_ptr<const LocalizabilityReport> Get(const std::string& name,
                                                  const LocalizabilityRequest& request);

 private:
  using Answer = std::shared_future<std::shared_ptr<const LocalizabilityReport>>;
  struct Entry {
    std::string name;
    LocalizabilityRequest request;
    std::weak_ptr<const LocalizationMap> map;  // MapCache::Loaded: expires with that map.
    Answer answer;  // Ready, or being computed by the caller that made the entry.
  };
  static constexpr size_t kMaxEntries = 16;

  std::shared_ptr<const LocalizabilityReport> Compute(const std::string& name,
                                                      const LocalizabilityRequest& request,
                                                      const LocalizationMap& map) const;

  MapCache* maps_;
  int max_poses_;
  int threads_;
  ComputeFn compute_;
  std::mutex mutex_;            // Guards entries_ only: never held while computing.
  std::vector<Entry> entries_;  // Most recent last.
};

}  // namespace visloc::server
