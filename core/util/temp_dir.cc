#include "core/util/temp_dir.h"

#include <stdlib.h>

#include <algorithm>
#include <filesystem>
#include <vector>

#include "core/util/check.h"

namespace visloc {

TempDir::TempDir(const std::string& prefix) {
  std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
  std::vector<char> buffer(pattern.begin(), pattern.end());
  buffer.push_back('\0');
  VISLOC_CHECK(mkdtemp(buffer.data()) != nullptr, "cannot create a temporary folder ", pattern);
  path_ = buffer.data();
}

std::vector<std::string> TempDir::FileNames() const {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(path_)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

}  // namespace visloc
