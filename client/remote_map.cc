#include "client/remote_map.h"

#include <grpcpp/grpcpp.h>

#include "client/map_report.h"
#include "client/outcome.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "mapstore/checksum.h"
#include "mapstore/map_store.h"
#include "proto/map_info_convert.h"
#include "visloc/v1/visloc.grpc.pb.h"

namespace visloc::cli {
namespace {

namespace v1 = ::visloc::v1;
constexpr size_t kChunkBytes = 1 << 20;

std::unique_ptr<v1::MapAdmin::Stub> Connect(const Connection& server) {
  return v1::MapAdmin::NewStub(server.OpenChannel());
}

// A server's map as the entry a local maps folder would list.
mapstore::MapDirectory::Entry EntryOf(const v1::MapInfo& info, const Connection& server) {
  return proto::FromProto(info, StrCat(info.name(), " on ", server.server));
}

}  // namespace

int RemoteMapList(const Connection& server, bool json) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::ListMapsResponse response;
  CheckCall(Connect(server)->ListMaps(&context, v1::ListMapsRequest(), &response), server.server);
  std::vector<mapstore::MapDirectory::Entry> entries;
  for (const v1::MapInfo& info : response.maps()) entries.push_back(EntryOf(info, server));
  return PrintMapList(entries, "on " + server.server, json);
}

int RemoteMapInfo(const Connection& server, const std::string& name, bool json) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::MapName request;
  request.set_name(name);
  v1::MapInfo info;
  CheckCall(Connect(server)->GetMapInfo(&context, request, &info), server.server);
  const mapstore::MapDirectory::Entry entry = EntryOf(info, server);
  if (!entry.info) throw InputError(StrCat(entry.path, ": unavailable: ", entry.error));
  return PrintMapInfo(*entry.info, json);
}

LocalizabilityReport RemoteLocalizability(const Connection& server, const std::string& name,
                                          const LocalizabilityOptions& options) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::LocalizabilityRequest request;
  request.set_map(name);
  request.set_cell_m(options.cell_m);
  request.set_headings(static_cast<uint32_t>(options.headings));
  request.set_has_height(options.height_m.has_value());
  request.set_height_m(options.height_m.value_or(0.0));
  request.set_has_pitch(options.pitch_deg.has_value());
  request.set_pitch_deg(options.pitch_deg.value_or(0.0));
  v1::Localizability answer;
  CheckCall(Connect(server)->GetLocalizability(&context, request, &answer), server.server);
  return proto::FromProto(answer);
}

int RemoteMapUpload(const Connection& server, const std::string& path, const std::string& name,
                    bool replace, bool force, bool json) {
  // Refuse to send what the server would refuse anyway, with the local file's problem.
  const mapstore::MapInfo local = mapstore::SummarizeMap(mapstore::LoadMap(path), path);
  const std::string bytes = ReadFileBytes(path);
  v1::UploadChunk chunk;
  v1::UploadHeader* header = chunk.mutable_header();
  header->set_name(name.empty() ? local.metadata.name : name);
  header->set_size_bytes(bytes.size());
  header->set_crc32(mapstore::Crc32(bytes));
  header->set_replace(replace);
  header->set_force(force);
  const std::string target = header->name();
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::MapInfo info;
  auto writer = Connect(server)->UploadMap(&context, &info);
  bool ok = writer->Write(chunk);
  for (size_t at = 0; ok && at < bytes.size(); at += kChunkBytes) {
    chunk.Clear();
    chunk.set_data(bytes.substr(at, kChunkBytes));
    ok = writer->Write(chunk);
  }
  writer->WritesDone();
  CheckCall(writer->Finish(), server.server);
  return PrintOutcome(json,
                      StrCat("uploaded ", path, " as '", target, "' (", bytes.size(), " bytes, ",
                             info.keyframes(), " keyframes, ", info.points(), " points)"),
                      {{"map", target},
                       {"server", server.server},
                       {"bytes", static_cast<int64_t>(bytes.size())},
                       {"keyframes", static_cast<int64_t>(info.keyframes())},
                       {"points", static_cast<int64_t>(info.points())},
                       {"replaced", static_cast<int64_t>(replace)}});
}

int RemoteMapDownload(const Connection& server, const std::string& name, const std::string& out,
                      bool json) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::MapName request;
  request.set_name(name);
  auto reader = Connect(server)->DownloadMap(&context, request);
  v1::DownloadChunk chunk;
  v1::UploadHeader header;
  std::string bytes;
  bool have_header = false;
  while (reader->Read(&chunk)) {
    if (chunk.has_header()) {
      header = chunk.header();
      have_header = true;
      bytes.reserve(header.size_bytes());
    } else {
      bytes += chunk.data();
    }
  }
  CheckCall(reader->Finish(), server.server);
  if (!have_header || bytes.size() != header.size_bytes() ||
      mapstore::Crc32(bytes) != header.crc32()) {
    throw InputError(StrCat("download of '", name, "' is incomplete or corrupt: ", bytes.size(),
                            " of ", header.size_bytes(), " bytes"));
  }
  WriteFileAtomically(out, bytes);
  const auto report = mapstore::VerifyMapFile(out);
  if (!report.ok()) throw InputError(out + ": downloaded map is not sound: " + report.problems[0]);
  return PrintOutcome(
      json, StrCat("downloaded '", name, "' to ", out, " (", bytes.size(),
                   " bytes, CRC-32 checked, map verified)"),
      {{"map", name}, {"out", out}, {"bytes", static_cast<int64_t>(bytes.size())}});
}

int RemoteMapDelete(const Connection& server, const std::string& name, bool force, bool json) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::MapName request;
  request.set_name(name);
  request.set_force(force);
  v1::Empty response;
  CheckCall(Connect(server)->DeleteMap(&context, request, &response), server.server);
  return PrintOutcome(json, StrCat("deleted '", name, "' on ", server.server),
                      {{"deleted", name}, {"server", server.server}});
}

int RemoteMapRename(const Connection& server, const std::string& from, const std::string& to,
                    bool json) {
  grpc::ClientContext context;
  server.Prepare(&context);
  v1::RenameMapRequest request;
  request.set_from(from);
  request.set_to(to);
  v1::MapInfo info;
  CheckCall(Connect(server)->RenameMap(&context, request, &info), server.server);
  return PrintOutcome(json, StrCat("renamed '", from, "' -> '", to, "' on ", server.server),
                      {{"renamed", from}, {"to", to}, {"server", server.server}});
}

}  // namespace visloc::cli
