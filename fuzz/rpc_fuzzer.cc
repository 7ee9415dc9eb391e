// Fuzz target: every RPC of the server, through a real gRPC server built in-process (the same
// services visloc-server registers, on an in-process channel instead of a port), on a maps
// folder holding one small map named "seed". The first byte picks the RPC; the rest is split
// into messages (fuzz_input.h), each parsed as that RPC's request type:
//   0 Localize (up to 12 stream messages)  1 Relocalize  2 ListMaps  3 GetMapInfo
//   4 UploadMap (up to 12 chunks)          5 DownloadMap 6 DeleteMap 7 RenameMap
//   8 GetLocalizability (its grid bounded to 20,000 poses)
// The server must answer every call with a status (never crash or hang); after each input the
// seed map is restored if a call removed it, and other maps are cleared, so inputs stay
// independent.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "core/map/synthetic_map.h"
#include "core/util/temp_dir.h"
#include "core/util/text_file.h"
#include "fuzz/fuzz_input.h"
#include "mapstore/map_store.h"
#include "server/auth.h"
#include "server/localization_service.h"
#include "server/map_admin_service.h"
#include "server/map_cache.h"

namespace visloc::fuzz {
namespace {

namespace fs = std::filesystem;
constexpr int kMaxMessages = 12;

class InProcessServer {
 public:
  InProcessServer()
      : maps_dir_("visloc-rpc-fuzz"),
        maps_(maps_dir_.path(), std::chrono::seconds(3600)),
        localization_(&maps_, Limits(), &auth_),
        localizability_(&maps_, 20'000, 1),
        admin_(&maps_, &localizability_, server::MapAdminOptions{4 << 20, false}, &auth_) {
    SyntheticMapOptions options;
    options.keyframes = 6;
    options.points = 200;
    options.vocabulary_depth = 1;
    options.appearance_from_descriptors = true;
    Map map = MakeSyntheticMap(options);
    map.metadata.name = "seed";
    mapstore::SaveMap(map, SeedPath(), mapstore::SaveMapOptions{4096});
    seed_bytes_ = ReadFileBytes(SeedPath());
    grpc::ServerBuilder builder;
    builder.RegisterService(&localization_);
    builder.RegisterService(&admin_);
    builder.SetMaxReceiveMessageSize(8 << 20);
    server_ = builder.BuildAndStart();
    channel_ = server_->InProcessChannel(grpc::ChannelArguments());
    localize_ = v1::Localization::NewStub(channel_);
    map_admin_ = v1::MapAdmin::NewStub(channel_);
  }

  v1::Localization::Stub& localize() { return *localize_; }
  v1::MapAdmin::Stub& map_admin() { return *map_admin_; }

  // Puts the seed map back as it was and removes whatever else the input created.
  void Reset() {
    for (const auto& entry : fs::directory_iterator(maps_dir_.path())) {
      if (entry.path() != SeedPath()) fs::remove_all(entry.path());
    }
    if (!fs::exists(SeedPath()) || ReadFileBytes(SeedPath()) != seed_bytes_) {
      WriteFileAtomically(SeedPath(), seed_bytes_);
    }
  }

 private:
  static server::ServiceLimits Limits() {
    server::ServiceLimits limits;
    limits.max_sessions = 4;
    limits.workers = 1;
    limits.wire.max_image_width = 256;  // Smaller than the server's 4096: fast inputs.
    limits.wire.max_image_height = 256;
    return limits;
  }
  std::string SeedPath() const { return maps_dir_.File("seed.db"); }

  TempDir maps_dir_;
  server::MapCache maps_;
  server::TokenAuth auth_;  // Disabled: every call allowed, so every handler is reached.
  server::LocalizationService localization_;
  server::LocalizabilityCache localizability_;
  server::MapAdminService admin_;
  std::string seed_bytes_;
  std::unique_ptr<grpc::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Localization::Stub> localize_;
  std::unique_ptr<v1::MapAdmin::Stub> map_admin_;
};

void SetDeadline(grpc::ClientContext* context) {
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
}

void Localize(InProcessServer& server, FuzzInput& input) {
  grpc::ClientContext context;
  SetDeadline(&context);
  auto stream = server.localize().Localize(&context);
  // As a robot's client does: one answer is read per frame before the next is sent (the
  // in-process transport completes a write only when the other side reads it).
  v1::LocalizeResponse response;
  bool open = true;
  int sent = 0;  // The first message sent opens the session and gets no answer.
  for (int i = 0; open && i < kMaxMessages && !input.empty(); ++i) {
    v1::LocalizeRequest request;
    if (!request.ParseFromString(input.Chunk())) continue;
    open = stream->Write(request) && (sent++ == 0 || stream->Read(&response));
  }
  stream->WritesDone();
  while (stream->Read(&response)) {
  }
  stream->Finish();
}

void Upload(InProcessServer& server, FuzzInput& input) {
  grpc::ClientContext context;
  SetDeadline(&context);
  v1::MapInfo reply;
  auto writer = server.map_admin().UploadMap(&context, &reply);
  for (int i = 0; i < kMaxMessages && !input.empty(); ++i) {
    v1::UploadChunk chunk;
    if (chunk.ParseFromString(input.Chunk()) && !writer->Write(chunk)) break;
  }
  writer->WritesDone();
  writer->Finish();
}

void Download(InProcessServer& server, const std::string& bytes) {
  v1::MapName name;
  if (!name.ParseFromString(bytes)) return;
  grpc::ClientContext context;
  SetDeadline(&context);
  auto reader = server.map_admin().DownloadMap(&context, name);
  v1::DownloadChunk chunk;
  while (reader->Read(&chunk)) {
  }
  reader->Finish();
}

// A unary call with the request parsed from `bytes`.
template <typename Request, typename Response, typename Call>
void Unary(const std::string& bytes, Call call) {
  Request request;
  if (!request.ParseFromString(bytes)) return;
  grpc::ClientContext context;
  SetDeadline(&context);
  Response response;
  call(&context, request, &response);
}

}  // namespace
}  // namespace visloc::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace visloc::fuzz;
  namespace v1 = visloc::v1;
  static InProcessServer* server = new InProcessServer();  // Lives for the whole run.
  FuzzInput input(data, size);
  auto& admin = server->map_admin();
  switch (input.Byte() % 9) {
    case 0:
      Localize(*server, input);
      break;
    case 1:
      Unary<v1::RelocalizeRequest, v1::RelocalizeResponse>(
          input.Rest(),
          [&](auto* c, const auto& r, auto* a) { return server->localize().Relocalize(c, r, a); });
      break;
    case 2:
      Unary<v1::ListMapsRequest, v1::ListMapsResponse>(
          input.Rest(), [&](auto* c, const auto& r, auto* a) { return admin.ListMaps(c, r, a); });
      break;
    case 3:
      Unary<v1::MapName, v1::MapInfo>(
          input.Rest(), [&](auto* c, const auto& r, auto* a) { return admin.GetMapInfo(c, r, a); });
      break;
    case 4:
      Upload(*server, input);
      break;
    case 5:
      Download(*server, input.Rest());
      break;
    case 6:
      Unary<v1::MapName, v1::Empty>(
          input.Rest(), [&](auto* c, const auto& r, auto* a) { return admin.DeleteMap(c, r, a); });
      break;
    case 7:
      Unary<v1::RenameMapRequest, v1::MapInfo>(
          input.Rest(), [&](auto* c, const auto& r, auto* a) { return admin.RenameMap(c, r, a); });
      break;
    default:
      Unary<v1::LocalizabilityRequest, v1::Localizability>(
          input.Rest(),
          [&](auto* c, const auto& r, auto* a) { return admin.GetLocalizability(c, r, a); });
      break;
  }
  server->Reset();
  return 0;
}
