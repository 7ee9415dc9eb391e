#include "client/connection.h"

#include <cstdlib>
#include <random>

#include "client/replicas.h"
#include "core/util/check.h"
#include "core/util/text_file.h"

namespace visloc::cli {

void Connection::AddFlags(ArgParser& parser, bool server_required) {
  parser.AddFlag("server", &server,
                 "visloc-server address HOST:PORT; replicas: a name with several addresses or "
                 "ipv4:A:PORT,B:PORT (each session goes to the next replica)",
                 server_required);
  parser.AddFlag("tls-ca", &tls_ca_path, "use TLS, trusting this CA certificate (PEM)");
  parser.AddFlag("tls-cert", &tls_cert_path,
                 "mutual TLS: this client's certificate (PEM; default: $VISLOC_TLS_CERT)");
  parser.AddFlag("tls-key", &tls_key_path,
                 "mutual TLS: its private key (PEM; default: $VISLOC_TLS_KEY)");
  parser.AddFlag("token", &token, "bearer token (default: $VISLOC_TOKEN)");
}

void Connection::ApplyEnvironment() {
  if (token.empty()) {
    if (const char* env = std::getenv("VISLOC_TOKEN")) token = env;
  }
  const auto from_env = [](std::string* value, const char* name) {
    if (value->empty()) {
      if (const char* env = std::getenv(name)) *value = env;
    }
  };
  from_env(&tls_ca_path, "VISLOC_TLS_CA");
  from_env(&tls_cert_path, "VISLOC_TLS_CERT");
  from_env(&tls_key_path, "VISLOC_TLS_KEY");
  if (tls_cert_path.empty() != tls_key_path.empty()) {
    throw UsageError("--tls-cert and --tls-key go together");
  }
  if (!tls_cert_path.empty() && tls_ca_path.empty()) {
    throw UsageError("a client certificate (--tls-cert) needs --tls-ca for the server's");
  }
}

std::shared_ptr<grpc::Channel> Connection::OpenChannel() const {
  // The same target and trust the client library gets (ToLibrary): one place reads them.
  client::SessionOptions resolved;
  ToLibrary(&resolved);
  const client::Credentials& c = resolved.credentials;
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (!c.tls_ca_pem.empty()) {
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = c.tls_ca_pem;
    options.pem_cert_chain = c.tls_cert_pem;
    options.pem_private_key = c.tls_key_pem;
    credentials = grpc::SslCredentials(options);
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(client::kMaxReceiveMessageBytes);
  // Replicas (a name with several addresses, or an ipv4:/ipv6: list): each new stream goes to
  // the next ready replica, starting at a random one per process (client/replicas.h).
  args.SetLoadBalancingPolicyName("round_robin");
  if (!c.tls_target_name.empty()) args.SetSslTargetNameOverride(c.tls_target_name);
  return grpc::CreateCustomChannel(resolved.server, credentials, args);
}

void Connection::ToLibrary(client::SessionOptions* options) const {
  std::mt19937 rng(std::random_device{}());
  const ReplicaTarget chosen = ChooseReplicaTarget(server, &rng);
  options->server = chosen.target;
  client::Credentials& c = options->credentials;
  c.token = token;
  if (!tls_ca_path.empty()) {
    c.tls_ca_pem = ReadFileBytes(tls_ca_path);
    if (!tls_cert_path.empty()) {
      c.tls_cert_pem = ReadFileBytes(tls_cert_path);
      c.tls_key_pem = ReadFileBytes(tls_key_path);
    }
    c.tls_target_name = chosen.tls_name;
  }
}

void Connection::Prepare(grpc::ClientContext* context) const {
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

void CheckCall(const grpc::Status& status, const std::string& server) {
  if (!status.ok()) {
    throw InputError(StrCat("server ", server, ": ", status.error_message(), " (gRPC code ",
                            static_cast<int>(status.error_code()), ")"));
  }
}

}  // namespace visloc::cli
