#include "server/map_admin_service.h"

#include "core/util/check.h"
#include "core/util/text_file.h"
#include "mapstore/checksum.h"
#include "mapstore/map_upload.h"
#include "proto/map_info_convert.h"
#include "server/log.h"
#include "server/rpc.h"

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

MapAdminService::MapAdminService(MapCache* maps, LocalizabilityCache* localizability,
                                 const MapAdminOptions& options, const TokenAuth* auth)
    : maps_(maps), localizability_(localizability), options_(options), auth_(auth) {}

Status MapAdminService::RefuseIfReadOnly() const {
  if (!options_.read_only) return Status::OK;
  return Status(StatusCode::FAILED_PRECONDITION,
                "this server's maps folder is read-only (--maps-read-only): upload, delete "
                "and rename maps through the fleet's admin server");
}

Status MapAdminService::ListMaps(grpc::ServerContext* context, const v1::ListMapsRequest*,
                                 v1::ListMapsResponse* response) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "ListMaps", [&] {
    for (const auto& entry : maps_->directory().List()) ToProto(entry, response->add_maps());
    return Status::OK;
  });
}

Status MapAdminService::GetMapInfo(grpc::ServerContext* context, const v1::MapName* request,
                                   v1::MapInfo* response) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "GetMapInfo", [&] {
    ToProto(maps_->directory().Describe(request->name()), response);
    return Status::OK;
  });
}

Status MapAdminService::GetLocalizability(grpc::ServerContext* context,
                                          const v1::LocalizabilityRequest* request,
                                          v1::Localizability* response) {
  return HandleRpc(*auth_, *context, Role::kLocalize, "GetLocalizability", [&] {
    LocalizabilityRequest wanted;
    if (request->cell_m() != 0) wanted.cell_m = request->cell_m();
    if (request->headings() != 0) wanted.headings = static_cast<int>(request->headings());
    if (request->has_height()) wanted.height_m = request->height_m();
    if (request->has_pitch()) wanted.pitch_deg = request->pitch_deg();
    proto::ToProto(*localizability_->Get(request->map(), wanted), response);
    return Status::OK;
  });
}

Status MapAdminService::UploadMap(grpc::ServerContext* context,
                                  grpc::ServerReader<v1::UploadChunk>* reader,
                                  v1::MapInfo* response) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "UploadMap", [&] {
    if (Status refused = RefuseIfReadOnly(); !refused.ok()) return refused;
    v1::UploadChunk chunk;
    if (!reader->Read(&chunk) || !chunk.has_header()) {
      return Status(StatusCode::INVALID_ARGUMENT, "an upload starts with a header");
    }
    const v1::UploadHeader header = chunk.header();
    try {
      mapstore::MapUpload upload(maps_->directory(), header.name(), header.size_bytes(),
                                 header.crc32(), options_.max_upload_bytes);
      if (Status refused = RefuseUpload(header); !refused.ok()) return refused;
      while (reader->Read(&chunk)) {
        if (chunk.kind_case() != v1::UploadChunk::kData) {
          throw InputError("a second header in the upload");
        }
        upload.Append(chunk.data());
      }
      if (context->IsCancelled()) {
        throw InputError(StrCat("upload cut off: ", upload.received_bytes(), " of ",
                                header.size_bytes(), " bytes arrived"));
      }
      ToProto(upload.Publish(header.replace()), response);
      Log("map_uploaded", {{"map", header.name()},
                           {"bytes", std::to_string(upload.received_bytes())},
                           {"peer", context->peer()}});
      return Status::OK;
    } catch (const std::exception& e) {
      Log("map_upload_failed", {{"map", header.name()}, {"reason", e.what()}});
      throw;
    }
  });
}

Status MapAdminService::RefuseUpload(const v1::UploadHeader& header) const {
  if (!maps_->directory().Contains(header.name())) return Status::OK;
  if (!header.replace()) {
    return Status(StatusCode::ALREADY_EXISTS,
                  "a map named '" + header.name() +
                      "' already exists; replace it with visloc map upload --replace (the "
                      "upload header's replace field)");
  }
  return RefuseIfInUse(*maps_, header.name(), header.force(), "replace",
                       "visloc map upload --replace --force");
}

Status MapAdminService::DownloadMap(grpc::ServerContext* context, const v1::MapName* request,
                                    grpc::ServerWriter<v1::DownloadChunk>* writer) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "DownloadMap", [&] {
    if (Status missing = RefuseIfMissing(request->name()); !missing.ok()) return missing;
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
  });
}

Status MapAdminService::DeleteMap(grpc::ServerContext* context, const v1::MapName* request,
                                  v1::Empty*) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "DeleteMap", [&] {
    if (Status refused = RefuseIfReadOnly(); !refused.ok()) return refused;
    if (Status missing = RefuseIfMissing(request->name()); !missing.ok()) return missing;
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
  });
}

Status MapAdminService::RenameMap(grpc::ServerContext* context, const v1::RenameMapRequest* request,
                                  v1::MapInfo* response) {
  return HandleRpc(*auth_, *context, Role::kAdmin, "RenameMap", [&] {
    if (Status refused = RefuseIfReadOnly(); !refused.ok()) return refused;
    if (Status missing = RefuseIfMissing(request->from()); !missing.ok()) return missing;
    mapstore::CheckMapName(request->to());
    if (maps_->directory().Contains(request->to())) {
      return Status(StatusCode::ALREADY_EXISTS,
                    "a map named '" + request->to() + "' already exists");
    }
    mapstore::MapDirectory(maps_->directory().dir()).Rename(request->from(), request->to());
    ToProto(maps_->directory().Describe(request->to()), response);
    Log("map_renamed",
        {{"from", request->from()}, {"to", request->to()}, {"peer", context->peer()}});
    return Status::OK;
  });
}

Status MapAdminService::RefuseIfMissing(const std::string& name) const {
  mapstore::CheckMapName(name);
  if (maps_->directory().Contains(name)) return Status::OK;
  return Status(StatusCode::NOT_FOUND, "no map named '" + name + "'");
}

}  // namespace visloc::server
