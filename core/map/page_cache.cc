#include "core/map/page_cache.h"

#include <algorithm>

#include "core/util/timer.h"

namespace visloc {

// Bytes of pages alive anywhere, updated when a page is loaded and when its last holder lets go.
struct PageCache::Counter {
  std::mutex mutex;
  size_t live = 0;
  size_t peak = 0;
  void Add(size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    live += bytes;
    peak = std::max(peak, live);
  }
  void Sub(size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    live -= bytes;
  }
};

PageCache::PageCache(size_t budget_bytes)
    : budget_bytes_(budget_bytes), live_(std::make_shared<Counter>()) {
  stats_.budget_bytes = budget_bytes;
}

std::shared_ptr<const void> PageCache::Get(uint64_t key, const Loader& load) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(key);
    if (it != entries_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      ++stats_.hits;
      return it->second.page;
    }
  }
  Timer timer;
  size_t bytes = 0;
  std::shared_ptr<const void> loaded = load(&bytes);
  const double load_ms = timer.ElapsedMs();
  // The handed-out pointer counts the page as live until its last holder, cache or session,
  // lets go; it keeps the loaded object alive through its deleter.
  live_->Add(bytes);
  std::shared_ptr<const void> page(loaded.get(),
                                   [holder = loaded, counter = live_, bytes](const void*) mutable {
                                     holder.reset();
                                     counter->Sub(bytes);
                                   });
  std::lock_guard<std::mutex> lock(mutex_);
  stats_.load_ms += load_ms;
  auto it = entries_.find(key);
  if (it != entries_.end()) return it->second.page;  // Another session loaded it meanwhile.
  ++stats_.loads;
  lru_.push_front(key);
  entries_[key] = {page, bytes, lru_.begin()};
  stats_.cached_bytes += bytes;
  EvictOverBudgetLocked();
  stats_.peak_cached_bytes = std::max(stats_.peak_cached_bytes, stats_.cached_bytes);
  return page;
}

void PageCache::EvictOverBudgetLocked() {
  // The newest page stays even when it alone exceeds the budget: its caller needs it.
  while (stats_.cached_bytes > budget_bytes_ && lru_.size() > 1) {
    const uint64_t oldest = lru_.back();
    lru_.pop_back();
    auto it = entries_.find(oldest);
    stats_.cached_bytes -= it->second.bytes;
    entries_.erase(it);
    ++stats_.evictions;
  }
}

PageCacheStats PageCache::stats() const {
  PageCacheStats stats;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats = stats_;
  }
  std::lock_guard<std::mutex> lock(live_->mutex);
  stats.live_bytes = live_->live;
  stats.peak_live_bytes = live_->peak;
  return stats;
}

}  // namespace visloc
