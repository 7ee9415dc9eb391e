#include "server/localizability_cache.h"

#include <algorithm>
#include <cmath>

#include "core/util/check.h"
#include "mapping/site_alignment.h"

namespace visloc::server {

LocalizabilityCache::LocalizabilityCache(MapCache* maps, int max_poses, int threads)
    : maps_(maps), max_poses_(max_poses), threads_(threads) {}

std::shared_ptr<const LocalizabilityReport> LocalizabilityCache::Get(
    const std::string& name, const LocalizabilityRequest& request) {
  if (!(request.cell_m >= 0.05 && request.cell_m <= 100.0)) {
    throw InputError(StrCat("localizability cell ", request.cell_m, " m: 0.05 to 100"));
  }
  if (request.headings < 1 || request.headings > 72) {
    throw InputError(StrCat("localizability headings ", request.headings, ": 1 to 72"));
  }
  if (request.pitch_deg && !(std::abs(*request.pitch_deg) < 90.0)) {
    throw InputError(StrCat("camera pitch ", *request.pitch_deg, " degrees: within (-90, 90)"));
  }
  if (request.height_m && !std::isfinite(*request.height_m)) {
    throw InputError("camera height: not a number");
  }
  const std::shared_ptr<const LocalizationMap> map = maps_->Acquire(name);
  const std::lock_guard<std::mutex> lock(mutex_);
  // Grids of maps no longer loaded (unloaded, replaced) go.
  entries_.erase(std::remove_if(entries_.begin(), entries_.end(),
                                [](const Entry& e) { return e.map.expired(); }),
                 entries_.end());
  for (const Entry& entry : entries_) {
    if (entry.name == name && entry.request == request && entry.map.lock() == map) {
      auto cached = std::make_shared<LocalizabilityReport>(*entry.answer);
      cached->stats.seconds = 0.0;  // Nothing computed for this request.
      return cached;
    }
  }
  std::string why_not;
  const std::optional<mapping::PlanFrame> frame = mapping::PlanFrameOf(map->map(), &why_not);
  if (!frame) throw InputError(StrCat("map '", name, "': ", why_not));
  LocalizabilityOptions options;
  options.cell_m = request.cell_m;
  options.headings = request.headings;
  options.height_m = request.height_m;
  options.pitch_deg = request.pitch_deg;
  options.threads = threads_;
  options.max_poses = max_poses_;
  auto answer = std::make_shared<LocalizabilityReport>();
  answer->map = name;
  answer->frame = frame->name;
  answer->frame_how = frame->how;
  answer->grid = ComputeLocalizability(*map, frame->site_from_map, options, &answer->stats);
  if (entries_.size() >= kMaxEntries) entries_.erase(entries_.begin());
  entries_.push_back({name, request, map, answer});
  return answer;
}

}  // namespace visloc::server
