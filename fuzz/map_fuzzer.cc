// Fuzz target: a map file as it arrives by upload or sits in the maps folder. The bytes are
// written to a file, loaded and indexed for localization (what a server session does on first
// use), opened paged and read page by page (what a server with --map-memory-mib does with a
// large map), and verified (VerifyMapFile, what uploads and `visloc map verify` run). A damaged
// file must end in an InputError or a failed verification, never a crash or a half-loaded map.

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "core/map/localization_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const visloc::TempDir dir("visloc-map-fuzz");
  const std::string path = dir.File("input.db");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  // The server loads a map on first use without the (slower) full verification, so loading
  // must hold up by itself; verification is tried separately.
  try {
    const visloc::LocalizationMap map(visloc::mapstore::LoadMap(path));
    (void)map.point_count();
  } catch (const visloc::InputError&) {
    // Refused with a message.
  }
  try {
    visloc::mapstore::PagedMap paged = visloc::mapstore::OpenPagedMap(path);
    const visloc::LocalizationMap map(std::move(paged.skeleton), paged.pages, 1 << 20);
    for (size_t k = 0; k < map.keyframe_count(); ++k) {
      const auto visible = map.VisiblePoints(k);
      const std::vector<uint32_t> ids(visible.begin(), visible.end());
      const visloc::PointView points = map.Points(ids);
      for (uint32_t id : ids) (void)points.position(id);
    }
  } catch (const visloc::InputError&) {
  }
  try {
    (void)visloc::mapstore::VerifyMapFile(path).ok();
  } catch (const visloc::InputError&) {
  }
  return 0;
}
