#pragma once
// Durable file publication inside mapstore: how SaveMap and MapDirectory::Publish stage a file
// beside its final path and make the rename survive a power cut.

#include <string>

namespace visloc::mapstore {

// fsync of a file (flags O_RDONLY) or of a folder (O_RDONLY | O_DIRECTORY). Throws InputError.
void SyncPath(const std::string& path, int flags);
// ".NAME.tmp-PID-N" beside `path`: unique per process, and recognisable by
// MapDirectory::RemoveStaleTemporaries once its writer is gone.
std::string TemporaryPathBeside(const std::string& path);

}  // namespace visloc::mapstore
