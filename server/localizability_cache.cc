#include "server/localizability_cache.h"

#include <algorithm>
#include <cmath>

#include "core/util/check.h"
#include "mapping/site_alignment.h"

namespace visloc::server {
namespace {

void CheckRequest(const LocalizabilityRequest& request) {
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
}

}  // namespace

LocalizabilityCache::LocalizabilityCache(MapCache* maps, int max_poses, int threads,
                                         ComputeFn compute)
    : maps_(maps),
      max_poses_(max_poses),
      threads_(threads),
      compute_(compute ? std::move(compute) : ComputeFn(ComputeLocalizability)) {}

std::shared_ptr<const LocalizabilityReport> LocalizabilityCache::Get(
    const std::string& name, const LocalizabilityRequest& request) {
  CheckRequest(request);
  const std::shared_ptr<const LocalizationMap> map = maps_->Acquire(name);
  // The loaded map itself, not this caller's lease of it (which ends with the call).
  const std::weak_ptr<const LocalizationMap> loaded = maps_->Loaded(name);
  std::promise<std::shared_ptr<const LocalizabilityReport>> computed;
  Answer answer;
  bool computing = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    // Grids of maps no longer loaded (unloaded, replaced) go.
    entries_.erase(std::remove_if(entries_.begin(), entries_.end(),
                                  [](const Entry& e) { return e.map.expired(); }),
                   entries_.end());
    const auto found = std::find_if(entries_.begin(), entries_.end(), [&](const Entry& e) {
      return e.name == name && e.request == request && e.map.lock().get() == map.get();
    });
    if (found != entries_.end()) {
      answer = found->answer;
    } else {
      answer = computed.get_future().share();
      computing = true;
      if (entries_.size() >= kMaxEntries) entries_.erase(entries_.begin());
      entries_.push_back({name, request, loaded, answer});
    }
  }
  if (!computing) {
    auto cached = std::make_shared<LocalizabilityReport>(*answer.get());  // Rethrows its error.
    cached->stats.seconds = 0.0;  // Nothing computed for this request.
    return cached;
  }
  try {
    computed.set_value(Compute(name, request, *map));
  } catch (...) {
    // A map without a level frame stays without one: its callers all get the reason.
    computed.set_exception(std::current_exception());
  }
  return answer.get();
}

std::shared_ptr<const LocalizabilityReport> LocalizabilityCache::Compute(
    const std::string& name, const LocalizabilityRequest& request,
    const LocalizationMap& map) const {
  std::string why_not;
  const std::optional<mapping::PlanFrame> frame = mapping::PlanFrameOf(map.map(), &why_not);
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
  answer->grid = compute_(map, frame->site_from_map, options, &answer->stats);
  return answer;
}

}  // namespace visloc::server
