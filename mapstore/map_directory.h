#pragma once
// A folder of maps, one file per map: DIR/NAME.db. The offline `visloc map list/delete/rename`
// verbs and the server's map registry both work through it.
//
// Map names are 1-64 characters of letters, digits, '.', '_' and '-', not starting with '.' or
// '-': a name can never reach outside the folder ("../x", "/etc/passwd") or hide a file.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mapstore/map_store.h"

namespace visloc::mapstore {

bool IsValidMapName(const std::string& name);
// Throws InputError naming the name and the rule.
void CheckMapName(const std::string& name);

class MapDirectory {
 public:
  // Throws InputError when `dir` is not a folder.
  explicit MapDirectory(std::string dir);

  const std::string& dir() const { return dir_; }
  // DIR/NAME.db for a valid name (whether or not it exists).
  std::string PathOf(const std::string& name) const;
  bool Contains(const std::string& name) const;

  struct Entry {
    std::string name;
    std::string path;
    uint64_t file_bytes = 0;
    std::optional<MapInfo> info;  // Set when the map loads.
    std::string error;            // Why it does not, otherwise.
  };
  // Every *.db file with a valid name, sorted by name; broken maps are listed with their error.
  std::vector<Entry> List() const;
  // The entry of one map (loading only that map). Throws NotFoundError when there is none and
  // InputError for an invalid name.
  Entry Describe(const std::string& name) const;

  // Throws NotFoundError "no map named NAME in DIR" when absent.
  void Remove(const std::string& name);
  // Renames the file and the map's own name (a durable rewrite, then the old file is removed).
  // Throws NotFoundError when `from` is absent, InputError when `to` exists or either name is
  // invalid.
  void Rename(const std::string& from, const std::string& to);
  // Where an incoming copy of NAME (an upload) is staged: a temporary file beside DIR/NAME.db,
  // invisible to List and removed by RemoveStaleTemporaries if its writer dies.
  std::string StagingPathFor(const std::string& name) const;
  // Verifies the staged file (VerifyMapFile) and publishes it as NAME with one atomic, durable
  // rename. An existing NAME is replaced only with `replace`. On any failure the staged file is
  // removed and InputError names the problem; DIR/NAME.db is then untouched.
  Entry Publish(const std::string& staged_path, const std::string& name, bool replace);

  // Removes temporary files of writers that are no longer running (left by a crash).
  // Returns how many were removed.
  int RemoveStaleTemporaries();

 private:
  Entry EntryFor(const std::string& name, const std::string& path) const;

  std::string dir_;
};

}  // namespace visloc::mapstore
