#pragma once
// The `visloc map` verbs against a server (`--server ADDR`), through the MapAdmin service.
// Each returns the process exit code; failures throw InputError with the server's message.

#include <string>

namespace visloc::cli {

int RemoteMapList(const std::string& server, bool json);
int RemoteMapInfo(const std::string& server, const std::string& name, bool json);
// `name` empty: the map's own name. Sends the file in chunks with its size and CRC-32.
int RemoteMapUpload(const std::string& server, const std::string& path, const std::string& name,
                    bool replace);
// Writes the map atomically to `out` after checking size, CRC-32 and the map itself.
int RemoteMapDownload(const std::string& server, const std::string& name, const std::string& out);
int RemoteMapDelete(const std::string& server, const std::string& name);
int RemoteMapRename(const std::string& server, const std::string& from, const std::string& to);

}  // namespace visloc::cli
