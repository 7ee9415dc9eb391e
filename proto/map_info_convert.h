#pragma once
// A map's summary on the wire (MapAdmin's MapInfo), both ways: the server describes an entry of
// its maps folder, the client turns it back into the entry `visloc map info`/`map list` print,
// so a remote map reads exactly as a local file does.

#include <string>

#include "core/localization/localizability.h"
#include "mapstore/map_directory.h"
#include "visloc/v1/visloc.pb.h"

namespace visloc::proto {

namespace v1 = ::visloc::v1;

// Everything but the entry's path (a server's paths are its own) and its error text (which the
// server redacts before it goes out).
void ToProto(const mapstore::MapDirectory::Entry& entry, v1::MapInfo* out);

// The entry a MapInfo describes, `path` standing for where it is (e.g. "lab on 10.0.0.5:50051").
// A map the server could not load has no info and its problem as the error. Throws InputError
// for an invalid camera or descriptor type.
mapstore::MapDirectory::Entry FromProto(const v1::MapInfo& info, const std::string& path);

// A map's localizability grid (core/localization/localizability.h) on the wire.
void ToProto(const LocalizabilityReport& report, v1::Localizability* out);
// Throws InputError when the grid's values do not match its size.
LocalizabilityReport FromProto(const v1::Localizability& in);

}  // namespace visloc::proto
