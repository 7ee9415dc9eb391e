#pragma once
// The `visloc map` verbs against a server (`--server ADDR`), through the MapAdmin service.
// Each returns the process exit code; failures throw InputError with the server's message.

#include <string>

#include "client/connection.h"
#include "core/localization/localizability.h"

namespace visloc::cli {

int RemoteMapList(const Connection& server, bool json);
int RemoteMapInfo(const Connection& server, const std::string& name, bool json);
// `name` empty: the map's own name. Sends the file in chunks with its size and CRC-32.
int RemoteMapUpload(const Connection& server, const std::string& path, const std::string& name,
                    bool replace, bool force, bool json);
// Writes the map atomically to `out` after checking size, CRC-32 and the map itself.
int RemoteMapDownload(const Connection& server, const std::string& name, const std::string& out,
                      bool json);
// `force`: although sessions use the map (the server refuses otherwise, with their count).
int RemoteMapDelete(const Connection& server, const std::string& name, bool force, bool json);
int RemoteMapRename(const Connection& server, const std::string& from, const std::string& to,
                    bool json);

// The server's localizability grid of map `name` (GetLocalizability); zero cell and headings
// take the server's defaults.
LocalizabilityReport RemoteLocalizability(const Connection& server, const std::string& name,
                                          const LocalizabilityOptions& options);

}  // namespace visloc::cli
