#pragma once
// A uniquely named scratch folder under the system temp directory, removed with its contents
// when the object goes out of scope. For tests and for tools that stage files.

#include <string>
#include <vector>

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
  // The names of what the folder holds now, sorted (a test's "nothing left behind").
  std::vector<std::string> FileNames() const;

 private:
  std::string path_;
};

}  // namespace visloc
