// visloc-server: the localization service for a fleet of robots (product.md).
//
//   visloc-server --maps DIR [--listen 127.0.0.1:50051] [--max-sessions N]
//
// Serves Localization, MapAdmin, grpc.health.v1 and server reflection. Prints
// "listening on ADDRESS" once ready (with port 0, the port chosen). SIGTERM or SIGINT drains:
// no new streams, open ones get a grace period, then the process exits 0.

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <thread>

#include "core/util/args.h"
#include "core/util/check.h"
#include "server/localization_service.h"
#include "server/log.h"
#include "server/map_admin_service.h"

namespace visloc::server {
namespace {

struct ServerArgs {
  std::string maps_dir;
  std::string listen = "127.0.0.1:50051";
  int max_sessions = 64;
  int idle_unload_s = 300;
  double drain_s = 5.0;
  int64_t max_upload_mb = 2048;
};

bool IsLoopback(const std::string& address) {
  return address.rfind("127.", 0) == 0 || address.rfind("localhost:", 0) == 0 ||
         address.rfind("[::1]:", 0) == 0;
}

int Run(int argc, char** argv) {
  ServerArgs args;
  ArgParser parser("visloc-server",
                   "Serves visual localization (Localization.Localize / Relocalize) and map "
                   "management (MapAdmin) over gRPC, with grpc.health.v1 and reflection.");
  parser.AddFlag("maps", &args.maps_dir, "folder of map files NAME.db", /*required=*/true);
  parser.AddFlag("listen", &args.listen, "address:port (port 0 picks a free port)");
  parser.AddFlag("max-sessions", &args.max_sessions, "concurrent Localize streams");
  parser.AddFlag("idle-unload-s", &args.idle_unload_s, "unload maps idle this long");
  parser.AddFlag("drain-s", &args.drain_s, "grace period for open streams at shutdown");
  parser.AddFlag("max-upload-mb", &args.max_upload_mb, "largest map upload accepted");
  if (!parser.Parse(std::vector<std::string>(argv + 1, argv + argc), std::cout)) return 0;
  if (args.max_sessions < 1) throw UsageError("--max-sessions must be at least 1");
  if (!IsLoopback(args.listen)) {
    throw UsageError("without authentication the server listens on loopback only (got " +
                     args.listen + ")");
  }

  // Block the shutdown signals in every thread; one thread waits for them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  MapCache maps(args.maps_dir, std::chrono::seconds(args.idle_unload_s));
  const int stale = mapstore::MapDirectory(args.maps_dir).RemoveStaleTemporaries();
  ServiceLimits limits;
  limits.max_sessions = args.max_sessions;
  LocalizationService localization(&maps, limits);
  MapAdminService admin(&maps, static_cast<uint64_t>(args.max_upload_mb) << 20);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(args.listen, grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&localization);
  builder.RegisterService(&admin);
  builder.SetMaxReceiveMessageSize(64 << 20);  // A raw 4096x4096 frame is 16 MiB.
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) throw InputError("cannot listen on " + args.listen);
  const std::string bound =
      args.listen.substr(0, args.listen.rfind(':')) + ":" + std::to_string(port);
  Log("server_start", {{"listen", bound},
                       {"maps", args.maps_dir},
                       {"max_sessions", std::to_string(args.max_sessions)},
                       {"stale_temporaries_removed", std::to_string(stale)}});
  std::printf("listening on %s\n", bound.c_str());
  std::fflush(stdout);

  std::atomic<bool> stopping{false};
  std::thread janitor([&] {
    while (!stopping) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      maps.UnloadIdle();
    }
  });
  int signal_number = 0;
  sigwait(&signals, &signal_number);
  Log("server_draining", {{"signal", signal_number == SIGTERM ? "SIGTERM" : "SIGINT"},
                          {"open_sessions", std::to_string(localization.active_sessions())}});
  server->Shutdown(std::chrono::system_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(args.drain_s * 1000)));
  server->Wait();
  stopping = true;
  janitor.join();
  Log("server_stop", {{"maps_loaded", std::to_string(maps.stats().loads)}});
  return 0;
}

}  // namespace
}  // namespace visloc::server

int main(int argc, char** argv) {
  try {
    return visloc::server::Run(argc, argv);
  } catch (const visloc::UsageError& e) {
    std::fprintf(stderr, "visloc-server: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "visloc-server: %s\n", e.what());
    return 1;
  }
}
