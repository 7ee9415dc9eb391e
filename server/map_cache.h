#pragma once
// The server's loaded maps: loaded from the maps folder on first use, shared read-only by every
// session that uses them (shared_ptr: a map stays alive while any session holds it), and
// dropped from the cache when idle. A map file replaced on disk (an upload, `visloc map
// build --out` into the folder) is noticed by its changed identity (inode, size, mtime): new
// sessions get the new map, running sessions keep the one they hold. Sessions asking for a map
// that is being loaded wait for that one load.
//
// With a memory bound per map (`--map-memory-mib`), a map whose points fit is loaded whole; a
// larger one is paged (LocalizationMap's paged mode): keyframes, kernel and appearance index
// resident, points and visibility lists read per keyframe region on demand into a cache of what
// the bound leaves. A map whose resident part alone exceeds the bound is refused, naming both.

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/map/localization_map.h"
#include "mapstore/map_directory.h"
#include "server/server_status.h"

namespace visloc::server {

struct MapCacheStats {
  int loads = 0;
  int paged_loads = 0;  // Of the loads, maps opened paged.
  int hits = 0;
  int unloads = 0;
  int load_failures = 0;  // Map files that did not load (a session or relocalization refused).
};

class MapCache {
 public:
  // `idle_unload` is how long a map no session holds stays loaded; `map_memory_bytes` bounds
  // each map's memory (0: no bound, every map loaded whole).
  MapCache(std::string maps_dir, std::chrono::seconds idle_unload, size_t map_memory_bytes = 0);

  // The map NAME, loading it if needed. Throws NotFoundError for a missing map ("no map named
  // ..."), InputError for an invalid name or a map file that does not load (the reason). The
  // caller holds the map as long as it keeps the pointer, and counts as its user meanwhile.
  std::shared_ptr<const LocalizationMap> Acquire(const std::string& name);
  // Throws what Acquire() would for a bad name or a map that does not exist, without loading
  // anything (a stat): the lasting reasons, told before a passing one such as the load.
  void CheckExists(const std::string& name) const;
  // How many holders of Acquire()'s pointers NAME has now (sessions localizing in it, a
  // relocalization under way), whichever version of the file they hold.
  int UsersOf(const std::string& name) const;
  // The map NAME as loaded now, without counting as its user: it expires once the cache has
  // dropped or replaced it and no holder of an Acquire() pointer to it remains. Empty when NAME
  // is not loaded. For what is computed once per loaded map (a localizability grid).
  std::weak_ptr<const LocalizationMap> Loaded(const std::string& name) const;
  // Drops maps no session holds that have been idle longer than the limit. Returns how many.
  int UnloadIdle();

  const mapstore::MapDirectory& directory() const { return directory_; }
  MapCacheStats stats() const;
  int loaded() const;
  // The maps loaded now, by name, with their users and memory.
  std::vector<LoadedMapStatus> LoadedMaps() const;

 private:
  struct FileIdentity {
    uint64_t inode = 0;
    uint64_t bytes = 0;
    int64_t mtime_ns = 0;
    bool operator==(const FileIdentity& o) const {
      return inode == o.inode && bytes == o.bytes && mtime_ns == o.mtime_ns;
    }
  };
  struct Entry {
    std::shared_ptr<const LocalizationMap> map;
    FileIdentity identity;
    std::chrono::steady_clock::time_point last_used;
  };
  static FileIdentity IdentityOf(const std::string& path);
  // The map at `path`, whole or paged as the memory bound decides.
  std::shared_ptr<const LocalizationMap> Load(const std::string& path, bool* paged) const;

  // The lock one name's (re)load holds, so sessions racing for a new map load it once while
  // other maps stay available.
  std::shared_ptr<std::mutex> LoadLockFor(const std::string& name);

  // The pointer Acquire() hands out: `map`, counted as a user of `name` while it lives.
  std::shared_ptr<const LocalizationMap> Lease(const std::string& name,
                                               std::shared_ptr<const LocalizationMap> map);

  // Users per map name; shared with the leases, which may outlive the cache.
  struct Users {
    std::mutex mutex;
    std::map<std::string, int> count;
  };

  mapstore::MapDirectory directory_;
  std::chrono::seconds idle_unload_;
  size_t map_memory_bytes_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
  std::map<std::string, std::shared_ptr<std::mutex>> load_locks_;
  MapCacheStats stats_;
  std::shared_ptr<Users> users_ = std::make_shared<Users>();
};

}  // namespace visloc::server
