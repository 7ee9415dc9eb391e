#pragma once
// The MapAdmin service: list, inspect, upload (checksummed chunks, published only when complete
// and verified), download, delete and rename maps in the server's maps folder. All file work
// goes through mapstore (MapDirectory, MapUpload); sessions holding a map keep it across delete
// or replace.

#include "server/auth.h"
#include "server/localizability_cache.h"
#include "server/map_cache.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::server {

struct MapAdminOptions {
  uint64_t max_upload_bytes = 2048ull << 20;  // Bounds an upload's declared and actual size.
  // A replica serving a shared maps folder that another server writes (docs/deployment.md):
  // upload, delete and rename are refused (FAILED_PRECONDITION) so changes go through one
  // place; list, info and download still work.
  bool read_only = false;
};

class MapAdminService final : public v1::MapAdmin::Service {
 public:
  // Every call but GetLocalizability needs the admin role. `maps`, `localizability` and `auth`
  // must outlive the service.
  MapAdminService(MapCache* maps, LocalizabilityCache* localizability,
                  const MapAdminOptions& options, const TokenAuth* auth);

  grpc::Status ListMaps(grpc::ServerContext*, const v1::ListMapsRequest*,
                        v1::ListMapsResponse* response) override;
  grpc::Status GetMapInfo(grpc::ServerContext*, const v1::MapName* request,
                          v1::MapInfo* response) override;
  grpc::Status UploadMap(grpc::ServerContext* context, grpc::ServerReader<v1::UploadChunk>* reader,
                         v1::MapInfo* response) override;
  grpc::Status DownloadMap(grpc::ServerContext* context, const v1::MapName* request,
                           grpc::ServerWriter<v1::DownloadChunk>* writer) override;
  grpc::Status DeleteMap(grpc::ServerContext*, const v1::MapName* request,
                         v1::Empty* response) override;
  grpc::Status RenameMap(grpc::ServerContext*, const v1::RenameMapRequest* request,
                         v1::MapInfo* response) override;
  grpc::Status GetLocalizability(grpc::ServerContext*, const v1::LocalizabilityRequest* request,
                                 v1::Localizability* response) override;

 private:
  // FAILED_PRECONDITION on a read-only replica, for the methods that change the folder.
  grpc::Status RefuseIfReadOnly() const;
  // NOT_FOUND for a valid name with no map (InputError for an invalid one).
  grpc::Status RefuseIfMissing(const std::string& name) const;
  // ALREADY_EXISTS without replace; a map in use without force.
  grpc::Status RefuseUpload(const v1::UploadHeader& header) const;

  MapCache* maps_;
  LocalizabilityCache* localizability_;
  MapAdminOptions options_;
  const TokenAuth* auth_;
};

}  // namespace visloc::server
