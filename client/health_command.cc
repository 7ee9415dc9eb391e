// `visloc health`: asks a server's grpc.health.v1 service whether it serves. Exit 0 when it
// does, 1 otherwise, so container health checks and scripts can use it as is (Debian has no
// grpc_health_probe). A draining server (SIGTERM) answers NOT_SERVING, so load balancers and
// orchestrators stop sending robots to it before it exits.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <iostream>

#include "client/commands.h"
#include "client/connection.h"
#include "core/util/args.h"
#include "core/util/check.h"
#include "core/util/json.h"
#include "core/util/strings.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace visloc::cli {
namespace {

const char* StatusName(grpc::health::v1::HealthCheckResponse::ServingStatus status) {
  using Response = grpc::health::v1::HealthCheckResponse;
  switch (status) {
    case Response::SERVING:
      return "SERVING";
    case Response::NOT_SERVING:
      return "NOT_SERVING";
    case Response::SERVICE_UNKNOWN:
      return "SERVICE_UNKNOWN";
    default:
      return "UNKNOWN";
  }
}

}  // namespace

int RunHealth(const Args& raw_args) {
  Connection server;
  std::string service;  // Empty: the server as a whole.
  double timeout_s = 3.0;
  bool json = false;
  ArgParser parser("visloc health",
                   "Asks visloc-server's grpc.health.v1 service whether it is serving. Exit 0 "
                   "when SERVING; 1 when not serving, draining or unreachable (the reason on "
                   "stderr). For container health checks and readiness probes.");
  server.AddFlags(parser);
  parser.AddFlag("service", &service,
                 "one service, e.g. visloc.v1.Localization (default: the whole server)");
  parser.AddFlag("timeout-s", &timeout_s, "give up after this many seconds");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  server.ApplyEnvironment();
  if (!(timeout_s > 0)) throw UsageError("--timeout-s must be positive");
  auto stub = grpc::health::v1::Health::NewStub(server.OpenChannel());
  grpc::ClientContext context;
  server.Prepare(&context);
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6)));
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  grpc::health::v1::HealthCheckResponse response;
  CheckCall(stub->Check(&context, request, &response), server.server);
  const bool serving = response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
  if (json) {
    std::cout << JsonWriter()
                     .BeginObject()
                     .Field("server", server.server)
                     .Field("service", service)
                     .Field("status", std::string(StatusName(response.status())))
                     .EndObject()
                     .str()
              << "\n";
  } else {
    std::cout << server.server << (service.empty() ? "" : " " + service) << ": "
              << StatusName(response.status()) << "\n";
  }
  return serving ? 0 : 1;
}

}  // namespace visloc::cli
