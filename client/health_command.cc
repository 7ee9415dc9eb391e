// `visloc health`: asks a server's grpc.health.v1 service whether it serves. Exit 0 when it
// does, 1 otherwise, so container health checks and scripts can use it as is (Debian has no
// grpc_health_probe). A draining server (SIGTERM) answers NOT_SERVING, so load balancers and
// orchestrators stop sending robots to it before it exits.

#include <grpcpp/grpcpp.h>
#include <httplib.h>

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

// The server's HTTP readiness (GET /readyz of `visloc-server --http`): exit 0 on 200.
int CheckHttpReadiness(const std::string& address, const std::string& ca_path, double timeout_s,
                       bool json) {
  const bool tls = !ca_path.empty();
  httplib::Client http((tls ? "https://" : "http://") + address);
  if (tls) http.set_ca_cert_path(ca_path.c_str());
  const auto timeout = std::chrono::microseconds(static_cast<int64_t>(timeout_s * 1e6));
  http.set_connection_timeout(timeout);
  http.set_read_timeout(timeout);
  const httplib::Result result = http.Get("/readyz");
  if (!result) {
    throw InputError("http " + address + ": no answer (" + httplib::to_string(result.error()) +
                     ")");
  }
  const bool ready = result->status == 200;
  std::string reason = result->body;
  while (!reason.empty() && reason.back() == '\n') reason.pop_back();
  if (json) {
    std::cout << JsonWriter()
                     .BeginObject()
                     .Field("http", address)
                     .Field("ready", ready)
                     .Field("answer", reason)
                     .EndObject()
                     .str()
              << "\n";
  } else {
    std::cout << address << " /readyz: " << result->status << " " << reason << "\n";
  }
  return ready ? 0 : 1;
}

int RunHealth(const Args& raw_args) {
  Connection server;
  std::string service;  // Empty: the server as a whole.
  std::string http;
  double timeout_s = 3.0;
  bool json = false;
  ArgParser parser("visloc health",
                   "Asks visloc-server's grpc.health.v1 service whether it is serving (or with "
                   "--http its /readyz). Exit 0 when SERVING (ready); 1 when not serving, "
                   "draining or unreachable (the reason on stderr). For container health checks "
                   "and readiness probes.");
  server.AddFlags(parser, /*server_required=*/false);
  parser.AddFlag("service", &service,
                 "one service, e.g. visloc.v1.Localization (default: the whole server)");
  parser.AddFlag("http", &http,
                 "HOST:PORT of the server's --http: ask /readyz instead (HTTPS with --tls-ca)");
  parser.AddFlag("timeout-s", &timeout_s, "give up after this many seconds");
  parser.AddSwitch("json", &json, "print one JSON object");
  if (!parser.Parse(raw_args, std::cout)) return 0;
  server.ApplyEnvironment();
  if (!(timeout_s > 0)) throw UsageError("--timeout-s must be positive");
  if (!http.empty()) return CheckHttpReadiness(http, server.tls_ca_path, timeout_s, json);
  if (server.server.empty()) {
    throw UsageError("--server (or --http) is required; see visloc health --help");
  }
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
