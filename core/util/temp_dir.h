#pragma once
// A uniquely named scratch folder under the system temp directory, removed with its contents
// when the object goes out of scope. For tests and for tools that stage files.

#include <string>

namespace visloc {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "visloc");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::string& path() const { return path_; }
  // path() + "/" + name
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

}  // namespace visloc
