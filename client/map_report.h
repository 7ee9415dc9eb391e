#pragma once
// How `visloc map info` and `visloc map list` print a map: one printer for a local file, a maps
// folder and a server's maps (which arrive as the same mapstore entries, proto/map_info_convert),
// so the same map reads the same wherever it is.

#include <string>
#include <vector>

#include "core/geometry/rigid3.h"
#include "core/util/json.h"
#include "mapstore/map_directory.h"
#include "mapstore/map_store.h"

namespace visloc::cli {

// `pose` as the object {tx, ty, tz, qw, qx, qy, qz} under `key` (the wire's Pose fields).
void WritePoseField(JsonWriter& json, const char* key, const Rigid3d& pose);

// The map's summary as text, or as one JSON object. Returns 0.
int PrintMapInfo(const mapstore::MapInfo& info, bool json);
// The entries of a maps folder as a table ending "N maps WHERE" (`where`: "in DIR" or "on
// SERVER"), or as a JSON array; a broken map is listed with its reason. Returns 0.
int PrintMapList(const std::vector<mapstore::MapDirectory::Entry>& entries,
                 const std::string& where, bool json);

}  // namespace visloc::cli
