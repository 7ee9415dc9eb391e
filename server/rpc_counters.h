#pragma once
// Every RPC the server finishes, counted by method and status code through a gRPC server
// interceptor (all services: visloc's, health, reflection), for visloc_rpcs_total. The method
// is the full gRPC name ("/visloc.v1.Localization/Localize"): a bounded label.

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/server_interceptor.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "server/server_status.h"

namespace visloc::server {

class RpcCounters {
 public:
  void Count(const std::string& method, grpc::StatusCode code);
  // (method, code name) -> calls.
  std::map<std::pair<std::string, std::string>, uint64_t> Snapshot() const;
  // The interceptor factory to register with the server builder; it counts into this.
  std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> InterceptorFactory();

 private:
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, grpc::StatusCode>, uint64_t> calls_;
};

// "OK", "INVALID_ARGUMENT", ... as gRPC names them.
const char* StatusCodeName(grpc::StatusCode code);

}  // namespace visloc::server
