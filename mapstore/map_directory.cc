#include "mapstore/map_directory.h"

#include <fcntl.h>
#include <signal.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "mapstore/file_sync.h"

namespace visloc::mapstore {
namespace fs = std::filesystem;

bool IsValidMapName(const std::string& name) {
  if (name.empty() || name.size() > 64 || name[0] == '.' || name[0] == '-') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
  });
}

void CheckMapName(const std::string& name) {
  if (!IsValidMapName(name)) {
    throw InputError(
        StrCat("invalid map name '", name,
               "': use 1-64 letters, digits, '.', '_' or '-', not starting with '.' or '-'"));
  }
}

MapDirectory::MapDirectory(std::string dir) : dir_(std::move(dir)) {
  if (!fs::is_directory(dir_)) throw InputError(StrCat(dir_, ": no such maps folder"));
}

std::string MapDirectory::PathOf(const std::string& name) const {
  CheckMapName(name);
  return (fs::path(dir_) / (name + ".db")).string();
}

bool MapDirectory::Contains(const std::string& name) const {
  return fs::is_regular_file(PathOf(name));
}

MapDirectory::Entry MapDirectory::EntryFor(const std::string& name, const std::string& path) const {
  Entry entry;
  entry.name = name;
  entry.path = path;
  std::error_code error;
  entry.file_bytes = fs::file_size(path, error);
  try {
    entry.info = SummarizeMap(LoadMap(path), path);
  } catch (const InputError& e) {
    entry.error = e.what();
  }
  return entry;
}

std::vector<MapDirectory::Entry> MapDirectory::List() const {
  std::vector<Entry> entries;
  for (const auto& file : fs::directory_iterator(dir_)) {
    const std::string filename = file.path().filename().string();
    if (!file.is_regular_file() || !EndsWith(filename, ".db")) continue;
    const std::string name = filename.substr(0, filename.size() - 3);
    if (IsValidMapName(name)) entries.push_back(EntryFor(name, file.path().string()));
  }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.name < b.name; });
  return entries;
}

MapDirectory::Entry MapDirectory::Describe(const std::string& name) const {
  CheckMapName(name);
  if (!Contains(name)) throw NotFoundError("no map named '" + name + "'");
  return EntryFor(name, PathOf(name));
}

void MapDirectory::Remove(const std::string& name) {
  const std::string path = PathOf(name);
  if (!fs::is_regular_file(path))
    throw NotFoundError(StrCat("no map named '", name, "' in ", dir_));
  fs::remove(path);
}

void MapDirectory::Rename(const std::string& from, const std::string& to) {
  const std::string from_path = PathOf(from), to_path = PathOf(to);
  if (!fs::is_regular_file(from_path))
    throw NotFoundError(StrCat("no map named '", from, "' in ", dir_));
  if (fs::exists(to_path))
    throw InputError(StrCat("a map named '", to, "' already exists in ", dir_));
  // The new file is complete and synced before the old one goes: a crash in between leaves
  // both, never neither.
  Map map = LoadMap(from_path);
  map.metadata.name = to;
  SaveMap(map, to_path);
  fs::remove(from_path);
}

std::string MapDirectory::StagingPathFor(const std::string& name) const {
  return TemporaryPathBeside(PathOf(name));
}

MapDirectory::Entry MapDirectory::Publish(const std::string& staged_path, const std::string& name,
                                          bool replace) {
  try {
    CheckMapName(name);
    if (!replace && Contains(name)) {
      throw InputError("a map named '" + name + "' already exists (replace it explicitly)");
    }
    const VerifyReport report = VerifyMapFile(staged_path);
    if (!report.ok()) throw InputError("the uploaded map is not sound: " + report.problems[0]);
    SyncPath(staged_path, O_RDONLY);
    const std::string path = PathOf(name);
    if (std::rename(staged_path.c_str(), path.c_str()) != 0) {
      throw InputError(path + ": cannot move the map into place: " + std::strerror(errno));
    }
    SyncPath(dir_, O_RDONLY | O_DIRECTORY);
    return EntryFor(name, path);
  } catch (...) {
    std::error_code ignored;
    fs::remove(staged_path, ignored);
    throw;
  }
}

int MapDirectory::RemoveStaleTemporaries() {
  int removed = 0;
  for (const auto& file : fs::directory_iterator(dir_)) {
    // SaveMap's temporaries: ".NAME.db.tmp-PID-N".
    const std::string filename = file.path().filename().string();
    const size_t mark = filename.rfind(".tmp-");
    if (filename[0] != '.' || mark == std::string::npos) continue;
    const auto pid = ParseInt64(Split(filename.substr(mark + 5), '-')[0]);
    if (pid && *pid > 0 && kill(static_cast<pid_t>(*pid), 0) == 0) continue;  // writer alive
    std::error_code error;
    if (fs::remove(file.path(), error)) ++removed;
  }
  return removed;
}

}  // namespace visloc::mapstore
