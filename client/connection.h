#pragma once
// How the client reaches a server: address, TLS trust and bearer token. Every remote verb takes
// the same flags (--server, --tls-ca, --token); the token may also come from $VISLOC_TOKEN and
// the CA from $VISLOC_TLS_CA, so they stay out of shell history.

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "core/util/args.h"

namespace visloc::cli {

struct Connection {
  std::string server;
  std::string tls_ca_path;  // Empty: plaintext.
  std::string token;        // Empty: no authorization metadata.

  // Adds --server, --tls-ca and --token to `parser`.
  void AddFlags(ArgParser& parser, bool server_required = true);
  // Fills unset fields from the environment; call after parsing.
  void ApplyEnvironment();
  std::shared_ptr<grpc::Channel> OpenChannel() const;
  // Attaches the token to a call.
  void Prepare(grpc::ClientContext* context) const;
};

// Throws InputError "server ADDR: message (gRPC code N)" for a failed call.
void CheckCall(const grpc::Status& status, const std::string& server);

}  // namespace visloc::cli
