#include "server/map_cache.h"

#include <malloc.h>
#include <sys/stat.h>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "mapstore/map_store.h"

namespace visloc::server {

MapCache::MapCache(std::string maps_dir, std::chrono::seconds idle_unload, size_t map_memory_bytes)
    : directory_(std::move(maps_dir)),
      idle_unload_(idle_unload),
      map_memory_bytes_(map_memory_bytes) {}

std::shared_ptr<const LocalizationMap> MapCache::Load(const std::string& path, bool* paged) const {
  *paged = false;
  if (map_memory_bytes_ == 0)
    return std::make_shared<const LocalizationMap>(mapstore::LoadMap(path));
  mapstore::PagedMap opened = mapstore::OpenPagedMap(path);
  const size_t resident = LocalizationMap::PagedResidentBytesFor(opened.skeleton);
  if (resident + opened.pages->BulkBytes() <= map_memory_bytes_) {
    return std::make_shared<const LocalizationMap>(mapstore::LoadMap(path));
  }
  // The cache needs room for a frame's pages: some point chunks and visibility lists.
  const size_t min_cache = 16 * (opened.pages->chunk_points() * (sizeof(MapPoint) + 64));
  if (resident + min_cache > map_memory_bytes_) {
    const auto mib = [](size_t bytes) { return FormatFixed(bytes / 1048576.0, 1); };
    throw InputError(StrCat(path, ": the map needs ", mib(resident + min_cache), " MiB at least (",
                            mib(resident),
                            " MiB of keyframes, kernel and appearance index resident, "
                            "and room for a frame's points), more than the server's "
                            "--map-memory-mib of ",
                            map_memory_bytes_ >> 20));
  }
  *paged = true;
  auto map = std::make_shared<const LocalizationMap>(std::move(opened.skeleton), opened.pages,
                                                     map_memory_bytes_ - resident);
  // Opening streamed the whole file and held the appearance vectors while the index was built:
  // give that memory back to the system, so the bound is what the process keeps.
  malloc_trim(0);
  return map;
}

namespace {

[[noreturn]] void ThrowNotFound(const std::string& name) {
  throw NotFoundError("no map named '" + name + "' in the server's maps folder");
}

}  // namespace

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

void MapCache::CheckExists(const std::string& name) const {
  mapstore::CheckMapName(name);
  if (IdentityOf(directory_.PathOf(name)).inode == 0) ThrowNotFound(name);
}

std::shared_ptr<const LocalizationMap> MapCache::Acquire(const std::string& name) {
  mapstore::CheckMapName(name);
  const std::string path = directory_.PathOf(name);
  const std::shared_ptr<std::mutex> load_lock = LoadLockFor(name);
  std::lock_guard<std::mutex> loading(*load_lock);
  const FileIdentity identity = IdentityOf(path);
  if (identity.inode == 0) ThrowNotFound(name);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = entries_.find(name);
    if (it != entries_.end() && it->second.identity == identity) {
      it->second.last_used = std::chrono::steady_clock::now();
      ++stats_.hits;
      return Lease(name, it->second.map);
    }
  }
  // Loaded under this name's lock only: other maps stay available meanwhile.
  bool paged = false;
  std::shared_ptr<const LocalizationMap> map;
  try {
    map = Load(path, &paged);
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.load_failures;
    throw;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  entries_[name] = {map, identity, std::chrono::steady_clock::now()};
  ++stats_.loads;
  stats_.paged_loads += paged ? 1 : 0;
  return Lease(name, map);
}

std::shared_ptr<const LocalizationMap> MapCache::Lease(const std::string& name,
                                                       std::shared_ptr<const LocalizationMap> map) {
  struct Held {
    std::shared_ptr<const LocalizationMap> map;
    std::shared_ptr<Users> users;
    std::string name;
    ~Held() {
      std::lock_guard<std::mutex> lock(users->mutex);
      if (--users->count[name] <= 0) users->count.erase(name);
    }
  };
  {
    std::lock_guard<std::mutex> lock(users_->mutex);
    ++users_->count[name];
  }
  auto held = std::make_shared<Held>();
  held->map = std::move(map);
  held->users = users_;
  held->name = name;
  const LocalizationMap* raw = held->map.get();
  return std::shared_ptr<const LocalizationMap>(std::move(held), raw);  // Aliasing: owns `held`.
}

int MapCache::UsersOf(const std::string& name) const {
  std::lock_guard<std::mutex> lock(users_->mutex);
  const auto it = users_->count.find(name);
  return it == users_->count.end() ? 0 : it->second;
}

std::weak_ptr<const LocalizationMap> MapCache::Loaded(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(name);
  return it == entries_.end() ? std::weak_ptr<const LocalizationMap>() : it->second.map;
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

std::vector<LoadedMapStatus> MapCache::LoadedMaps() const {
  std::vector<std::pair<std::string, std::shared_ptr<const LocalizationMap>>> maps;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [name, entry] : entries_) maps.emplace_back(name, entry.map);
  }
  std::vector<LoadedMapStatus> loaded;
  for (const auto& [name, map] : maps) {
    loaded.push_back({name, UsersOf(name), map->paged(), map->MemoryBytes()});
  }
  return loaded;
}

}  // namespace visloc::server
