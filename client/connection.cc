#include "client/connection.h"

#include <cstdlib>

#include "core/util/check.h"
#include "core/util/text_file.h"

namespace visloc::cli {

void Connection::AddFlags(ArgParser& parser, bool server_required) {
  parser.AddFlag("server", &server, "visloc-server address HOST:PORT", server_required);
  parser.AddFlag("tls-ca", &tls_ca_path, "use TLS, trusting this CA certificate (PEM)");
  parser.AddFlag("token", &token, "bearer token (default: $VISLOC_TOKEN)");
}

void Connection::ApplyEnvironment() {
  if (token.empty()) {
    if (const char* env = std::getenv("VISLOC_TOKEN")) token = env;
  }
  if (tls_ca_path.empty()) {
    if (const char* env = std::getenv("VISLOC_TLS_CA")) tls_ca_path = env;
  }
}

std::shared_ptr<grpc::Channel> Connection::OpenChannel() const {
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (!tls_ca_path.empty()) {
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = ReadFileBytes(tls_ca_path);
    credentials = grpc::SslCredentials(options);
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  return grpc::CreateCustomChannel(server, credentials, args);
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
