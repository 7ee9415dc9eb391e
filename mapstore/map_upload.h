#pragma once
// A map file arriving in pieces (the server's UploadMap): staged beside the maps folder's files
// (MapDirectory::StagingPathFor), checked against the size and CRC-32 its sender declared, and
// published under its name with one atomic rename only when complete and a sound map
// (MapDirectory::Publish). An upload that is abandoned, cut off or wrong leaves no file behind
// and the published map untouched.

#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>

#include "mapstore/map_directory.h"

namespace visloc::mapstore {

class MapUpload {
 public:
  // Throws InputError for an invalid name, a declared size outside 1..`max_bytes`, or a folder
  // where nothing can be staged.
  MapUpload(const MapDirectory& directory, std::string name, uint64_t declared_bytes,
            uint32_t declared_crc32, uint64_t max_bytes);
  // Removes the staged file unless it was published.
  ~MapUpload();
  MapUpload(const MapUpload&) = delete;
  MapUpload& operator=(const MapUpload&) = delete;

  // Throws InputError when the bytes go beyond the declared size or cannot be written.
  void Append(std::string_view bytes);
  // Throws InputError when fewer bytes than declared arrived, their CRC-32 differs, or the
  // staged file is not a sound map (then it is removed and a map of that name stays as it was).
  // An existing map of the name is replaced only with `replace`.
  MapDirectory::Entry Publish(bool replace);

  uint64_t received_bytes() const { return received_; }

 private:
  MapDirectory directory_;
  std::string name_;
  uint64_t declared_bytes_;
  uint32_t declared_crc32_;
  std::string staged_path_;
  std::ofstream out_;
  uint64_t received_ = 0;
  uint32_t crc32_ = 0;
  bool published_ = false;
};

}  // namespace visloc::mapstore
