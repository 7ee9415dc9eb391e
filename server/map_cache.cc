#include "server/map_cache.h"

#include <sys/stat.h>

#include "core/util/check.h"
#include "mapstore/map_store.h"

namespace visloc::server {

MapCache::MapCache(std::string maps_dir, std::chrono::seconds idle_unload)
    : directory_(std::move(maps_dir)), idle_unload_(idle_unload) {}

MapCache::FileIdentity MapCache::IdentityOf(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  return {static_cast<uint64_t>(st.st_ino), static_cast<uint64_t>(st.st_size),
          static_cast<int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec};
}

std::shared_ptr<std::mutex> MapCache::LoadLockFor(const std::string& name) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::shared_ptr<std::mutex>& load_lock = load_locks_[name];
  if (!load_lock) load_lock = std::make_shared<std::mutex>();
  return load_lock;
}

std::shared_ptr<const LocalizationMap> MapCache::Acquire(const std::string& name) {
  mapstore::CheckMapName(name);
  const std::string path = directory_.PathOf(name);
  const std::shared_ptr<std::mutex> load_lock = LoadLockFor(name);
  std::lock_guard<std::mutex> loading(*load_lock);
  const FileIdentity identity = IdentityOf(path);
  if (identity.inode == 0) {
    throw NotFoundError("no map named '" + name + "' in the server's maps folder");
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(name);
    if (it != entries_.end() && it->second.identity == identity) {
      it->second.last_used = std::chrono::steady_clock::now();
      ++stats_.hits;
      return it->second.map;
    }
  }
  // Loaded under this name's lock only: other maps stay available meanwhile.
  auto map = std::make_shared<const LocalizationMap>(mapstore::LoadMap(path));
  std::lock_guard<std::mutex> lock(mutex_);
  entries_[name] = {map, identity, std::chrono::steady_clock::now()};
  ++stats_.loads;
  return map;
}

int MapCache::UnloadIdle() {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  int unloaded = 0;
  for (auto it = entries_.begin(); it != entries_.end();) {
    // use_count 1: only the cache holds it.
    if (it->second.map.use_count() == 1 && now - it->second.last_used > idle_unload_) {
      it = entries_.erase(it);
      ++unloaded;
    } else {
      ++it;
    }
  }
  stats_.unloads += unloaded;
  return unloaded;
}

MapCacheStats MapCache::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

int MapCache::loaded() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(entries_.size());
}

}  // namespace visloc::server
