#pragma once
// The frame every gRPC handler runs in: the caller's token checked for the role the method
// needs (TokenAuth), then the handler's body, whose exceptions become the status a client may
// see (client_errors.h: redacted, internal errors as a log reference). Handlers hold only their
// own logic.

#include <grpcpp/grpcpp.h>

#include <exception>

#include "server/auth.h"
#include "server/client_errors.h"

namespace visloc::server {

// The decision as a gRPC status: UNAUTHENTICATED, PERMISSION_DENIED or OK.
grpc::Status ToStatus(const AuthDecision& decision);

// The role check on the call's "authorization" metadata.
grpc::Status Authorize(const TokenAuth& auth, const grpc::ServerContext& context, Role needed);

// Authorize, then `body()` (which returns a grpc::Status); an exception it throws becomes
// StatusFromException(e, where).
template <typename Body>
grpc::Status HandleRpc(const TokenAuth& auth, const grpc::ServerContext& context, Role needed,
                       const char* where, Body&& body) {
  if (grpc::Status allowed = Authorize(auth, context, needed); !allowed.ok()) return allowed;
  try {
    return body();
  } catch (const std::exception& e) {
    return StatusFromException(e, where);
  }
}

}  // namespace visloc::server
