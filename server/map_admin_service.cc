#include "server/map_admin_service.h"

#include <filesystem>
#include <fstream>

#include "core/util/check.h"
#include "core/util/text_file.h"
#include "mapstore/checksum.h"
#include "proto/map_info_convert.h"
#include "server/client_errors.h"
#include "server/localization_service.h"
#include "server/log.h"

namespace visloc::server {
namespace {

using grpc::Status;
using grpc::StatusCode;

constexpr size_t kChunkBytes = 1 << 20;

// The entry as the client sees it: no server paths, and a problem redacted for clients.
void ToProto(const mapstore::MapDirectory::Entry& entry, v1::MapInfo* out) {
  proto::ToProto(entry, out);
  out->set_problem(RedactForClient(entry.error));
}

// Refuses to delete or replace a map sessions are localizing in, unless forced: the operator
// should know robots are on it. `how` is the command that would force it.
Status RefuseIfInUse(const MapCache& maps, const std::string& name, bool force,
                     const std::string& what, const std::string& how) {
  const int users = maps.UsersOf(name);
  if (force || users == 0) return Status::OK;
  return Status(StatusCode::FAILED_PRECONDITION,
                StrCat("map '", name, "' is in use by ", users,
                       users == 1 ? " session" : " sessions", "; ", what, " it anyway with ", how,
                       " (running sessions keep the map they hold until they end)"));
}

}  // namespace

MapAdminService::MapAdminService(MapCache* maps, const MapAdminOptions& options,
                                 const TokenAuth* auth)
    : maps_(maps), options_(options), auth_(auth) {}

Status MapAdminService::MayChange(const grpc::ServerContext& context) const {
  if (Status allowed = auth_->Check(context, Role::kAdmin); !allowed.ok()) return allowed;
  if (options_.read_only) {
    return Status(StatusCode::FAILED_PRECONDITION,
                  "this server's maps folder is read-only (--maps-read-only): upload, delete "
                  "and rename maps through the fleet's admin server");
  }
  return Status::OK;
}

Status MapAdminService::ListMaps(grpc::ServerContext* context, const v1::ListMapsRequest*,
                                 v1::ListMapsResponse* response) {
  if (Status allowed = auth_->Check(*context, Role::kAdmin); !allowed.ok()) return allowed;
  try {
    for (const auto& entry : maps_->directory().List()) ToProto(entry, response->add_maps());
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "ListMaps");
  }
}

Status MapAdminService::GetMapInfo(grpc::ServerContext* context, const v1::MapName* request,
                                   v1::MapInfo* response) {
  if (Status allowed = auth_->Check(*context, Role::kAdmin); !allowed.ok()) return allowed;
  try {
    ToProto(maps_->directory().Describe(request->name()), response);
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "GetMapInfo");
  }
}

Status MapAdminService::UploadMap(grpc::ServerContext* context,
                                  grpc::ServerReader<v1::UploadChunk>* reader,
                                  v1::MapInfo* response) {
  if (Status allowed = MayChange(*context); !allowed.ok()) return allowed;
  v1::UploadChunk chunk;
  if (!reader->Read(&chunk) || !chunk.has_header()) {
    return Status(StatusCode::INVALID_ARGUMENT, "an upload starts with a header");
  }
  const v1::UploadHeader header = chunk.header();
  std::string staged;
  try {
    mapstore::CheckMapName(header.name());
    if (header.size_bytes() == 0 || header.size_bytes() > options_.max_upload_bytes) {
      return Status(StatusCode::INVALID_ARGUMENT,
                    StrCat("upload size ", header.size_bytes(), " bytes outside 1..",
                           options_.max_upload_bytes));
    }
    if (!header.replace() && maps_->directory().Contains(header.name())) {
      return Status(StatusCode::ALREADY_EXISTS,
                    "a map named '" + header.name() +
                        "' already exists; replace it with visloc map upload --replace (the "
                        "upload header's replace field)");
    }
    if (header.replace() && maps_->directory().Contains(header.name())) {
      if (Status in_use = RefuseIfInUse(*maps_, header.name(), header.force(), "replace",
                                        "visloc map upload --replace --force");
          !in_use.ok()) {
        return in_use;
      }
    }
    staged = maps_->directory().StagingPathFor(header.name());
    uint64_t received = 0;
    uint32_t crc = 0;
    {
      std::ofstream out(staged, std::ios::binary | std::ios::trunc);
      if (!out) throw InputError("cannot stage the upload in the maps folder");
      while (reader->Read(&chunk)) {
        if (!chunk.has_data() && chunk.kind_case() != v1::UploadChunk::kData) {
          throw InputError("a second header in the upload");
        }
        received += chunk.data().size();
        if (received > header.size_bytes()) {
          throw InputError(
              StrCat("upload exceeds its declared size of ", header.size_bytes(), " bytes"));
        }
        crc = mapstore::Crc32(chunk.data(), crc);
        out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
      }
      if (!out.flush()) throw InputError("cannot write the upload (disk full?)");
    }
    if (context->IsCancelled() || received != header.size_bytes()) {
      throw InputError(
          StrCat("upload cut off: ", received, " of ", header.size_bytes(), " bytes arrived"));
    }
    if (crc != header.crc32()) {
      throw InputError(
          StrCat("upload checksum mismatch: CRC-32 ", crc, ", header says ", header.crc32()));
    }
    ToProto(mapstore::MapDirectory(maps_->directory().dir())
                .Publish(staged, header.name(), header.replace()),
            response);
    Log("map_uploaded",
        {{"map", header.name()}, {"bytes", std::to_string(received)}, {"peer", context->peer()}});
    return Status::OK;
  } catch (const std::exception& e) {
    std::error_code ignored;
    if (!staged.empty()) std::filesystem::remove(staged, ignored);
    Log("map_upload_failed", {{"map", header.name()}, {"reason", e.what()}});
    return StatusFromException(e, "UploadMap");
  }
}

Status MapAdminService::DownloadMap(grpc::ServerContext* context, const v1::MapName* request,
                                    grpc::ServerWriter<v1::DownloadChunk>* writer) {
  if (Status allowed = auth_->Check(*context, Role::kAdmin); !allowed.ok()) return allowed;
  try {
    mapstore::CheckMapName(request->name());
    if (!maps_->directory().Contains(request->name())) {
      return Status(StatusCode::NOT_FOUND, "no map named '" + request->name() + "'");
    }
    // Read the whole file first: a concurrent replace renames a new file into place, so the
    // open file stays the old, complete map.
    const std::string bytes = ReadFileBytes(maps_->directory().PathOf(request->name()));
    v1::DownloadChunk chunk;
    v1::UploadHeader* header = chunk.mutable_header();
    header->set_name(request->name());
    header->set_size_bytes(bytes.size());
    header->set_crc32(mapstore::Crc32(bytes));
    if (!writer->Write(chunk)) return Status(StatusCode::CANCELLED, "client went away");
    for (size_t at = 0; at < bytes.size(); at += kChunkBytes) {
      chunk.Clear();
      chunk.set_data(bytes.substr(at, kChunkBytes));
      if (!writer->Write(chunk)) return Status(StatusCode::CANCELLED, "client went away");
    }
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "DownloadMap");
  }
}

Status MapAdminService::DeleteMap(grpc::ServerContext* context, const v1::MapName* request,
                                  v1::Empty*) {
  if (Status allowed = MayChange(*context); !allowed.ok()) return allowed;
  try {
    mapstore::CheckMapName(request->name());
    if (!maps_->directory().Contains(request->name())) {
      return Status(StatusCode::NOT_FOUND, "no map named '" + request->name() + "'");
    }
    if (Status in_use = RefuseIfInUse(*maps_, request->name(), request->force(), "delete",
                                      "visloc map delete --force");
        !in_use.ok()) {
      return in_use;
    }
    mapstore::MapDirectory(maps_->directory().dir()).Remove(request->name());
    Log("map_deleted", {{"map", request->name()},
                        {"sessions_using", StrCat(maps_->UsersOf(request->name()))},
                        {"peer", context->peer()}});
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "DeleteMap");
  }
}

Status MapAdminService::RenameMap(grpc::ServerContext* context, const v1::RenameMapRequest* request,
                                  v1::MapInfo* response) {
  if (Status allowed = MayChange(*context); !allowed.ok()) return allowed;
  try {
    mapstore::CheckMapName(request->from());
    mapstore::CheckMapName(request->to());
    if (!maps_->directory().Contains(request->from())) {
      return Status(StatusCode::NOT_FOUND, "no map named '" + request->from() + "'");
    }
    if (maps_->directory().Contains(request->to())) {
      return Status(StatusCode::ALREADY_EXISTS,
                    "a map named '" + request->to() + "' already exists");
    }
    mapstore::MapDirectory(maps_->directory().dir()).Rename(request->from(), request->to());
    ToProto(maps_->directory().Describe(request->to()), response);
    Log("map_renamed",
        {{"from", request->from()}, {"to", request->to()}, {"peer", context->peer()}});
    return Status::OK;
  } catch (const std::exception& e) {
    return StatusFromException(e, "RenameMap");
  }
}

}  // namespace visloc::server
