#pragma once
// How the client reaches a server: address, TLS trust (and for mutual TLS the client's own
// certificate) and bearer token. Every remote verb takes the same flags (--server, --tls-ca,
// --tls-cert, --tls-key, --token); each may also come from the environment ($VISLOC_TOKEN,
// $VISLOC_TLS_CA, $VISLOC_TLS_CERT, $VISLOC_TLS_KEY), so secrets stay out of shell history.

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "core/util/args.h"
#include "visloc/client/session.h"

namespace visloc::cli {

struct Connection {
  std::string server;
  std::string tls_ca_path;                  // Empty: plaintext.
  std::string tls_cert_path, tls_key_path;  // Mutual TLS: the client's certificate and key.
  std::string token;                        // Empty: no authorization metadata.

  // Adds --server, --tls-ca and --token to `parser`.
  void AddFlags(ArgParser& parser, bool server_required = true);
  // Fills unset fields from the environment; call after parsing.
  void ApplyEnvironment();
  std::shared_ptr<grpc::Channel> OpenChannel() const;
  // Attaches the token to a call.
  void Prepare(grpc::ClientContext* context) const;
  // The client library's server target and credentials (PEM files read now).
  void ToLibrary(client::SessionOptions* options) const;
};

// Throws InputError "server ADDR: message (gRPC code N)" for a failed call.
void CheckCall(const grpc::Status& status, const std::string& server);

}  // namespace visloc::cli
