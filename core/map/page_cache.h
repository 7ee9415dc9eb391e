#pragma once
// A byte-bounded least-recently-used cache of immutable pages (a paged map's point chunks and
// visibility lists), shared by every session on the map and safe to use from many threads.
//
// A page is handed out as a shared_ptr: a session pins the pages one frame needs for as long as
// it works on them, so evicting a page only drops the cache's reference. What the process
// really holds is therefore the cached pages plus the pages pinned by frames in flight that were
// evicted meanwhile; `live_bytes` counts exactly that, and its peak is the figure to compare
// with the budget (a frame pins a few pages, so it exceeds the budget by at most those).
//
// Loads run outside the lock, so a slow read blocks no other page; two sessions missing the
// same page at once may both load it (the second copy is dropped).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>

namespace visloc {

struct PageCacheStats {
  size_t budget_bytes = 0;
  uint64_t hits = 0;
  uint64_t loads = 0;
  uint64_t evictions = 0;
  size_t cached_bytes = 0;  // Pages the cache holds.
  size_t peak_cached_bytes = 0;
  size_t live_bytes = 0;  // Pages alive anywhere: cached or pinned by a session.
  size_t peak_live_bytes = 0;
  double load_ms = 0.0;  // Time spent loading pages, summed.
};

class PageCache {
 public:
  // Loads page `key`: returns it and sets `*bytes` to its size.
  using Loader = std::function<std::shared_ptr<const void>(size_t* bytes)>;

  explicit PageCache(size_t budget_bytes);

  // The page `key`, loaded with `load` when not cached. Exceptions from `load` propagate and
  // nothing is cached.
  std::shared_ptr<const void> Get(uint64_t key, const Loader& load);

  PageCacheStats stats() const;

 private:
  struct Counter;
  struct Entry {
    std::shared_ptr<const void> page;
    size_t bytes = 0;
    std::list<uint64_t>::iterator lru;  // Position in lru_ (front: most recent).
  };
  void EvictOverBudgetLocked();

  const size_t budget_bytes_;
  std::shared_ptr<Counter> live_;  // Outlives the cache while pages are pinned.
  mutable std::mutex mutex_;
  std::unordered_map<uint64_t, Entry> entries_;
  std::list<uint64_t> lru_;
  PageCacheStats stats_;
};

}  // namespace visloc
