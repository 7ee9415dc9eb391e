#include "mapstore/map_upload.h"

#include <filesystem>

#include "core/util/check.h"
#include "mapstore/checksum.h"

namespace visloc::mapstore {

MapUpload::MapUpload(const MapDirectory& directory, std::string name, uint64_t declared_bytes,
                     uint32_t declared_crc32, uint64_t max_bytes)
    : directory_(directory),
      name_(std::move(name)),
      declared_bytes_(declared_bytes),
      declared_crc32_(declared_crc32) {
  CheckMapName(name_);
  if (declared_bytes == 0 || declared_bytes > max_bytes) {
    throw InputError(StrCat("upload size ", declared_bytes, " bytes outside 1..", max_bytes));
  }
  staged_path_ = directory_.StagingPathFor(name_);
  out_.open(staged_path_, std::ios::binary | std::ios::trunc);
  if (!out_) throw InputError("cannot stage the upload in the maps folder");
}

MapUpload::~MapUpload() {
  if (published_) return;
  out_.close();
  std::error_code ignored;
  std::filesystem::remove(staged_path_, ignored);
}

void MapUpload::Append(std::string_view bytes) {
  if (received_ + bytes.size() > declared_bytes_) {
    throw InputError(StrCat("upload exceeds its declared size of ", declared_bytes_, " bytes"));
  }
  received_ += bytes.size();
  crc32_ = Crc32(bytes, crc32_);
  out_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out_) throw InputError("cannot write the upload (disk full?)");
}

MapDirectory::Entry MapUpload::Publish(bool replace) {
  if (!out_.flush()) throw InputError("cannot write the upload (disk full?)");
  out_.close();
  if (received_ != declared_bytes_) {
    throw InputError(
        StrCat("upload cut off: ", received_, " of ", declared_bytes_, " bytes arrived"));
  }
  if (crc32_ != declared_crc32_) {
    throw InputError(
        StrCat("upload checksum mismatch: CRC-32 ", crc32_, ", header says ", declared_crc32_));
  }
  // Publish removes the staged file itself when the map is refused.
  MapDirectory::Entry entry = directory_.Publish(staged_path_, name_, replace);
  published_ = true;
  return entry;
}

}  // namespace visloc::mapstore
