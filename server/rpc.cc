#include "server/rpc.h"

namespace visloc::server {

grpc::Status ToStatus(const AuthDecision& decision) {
  switch (decision.outcome) {
    case AuthDecision::Outcome::kAllowed:
      return grpc::Status::OK;
    case AuthDecision::Outcome::kUnauthenticated:
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, decision.message);
    case AuthDecision::Outcome::kPermissionDenied:
      return grpc::Status(grpc::StatusCode::PERMISSION_DENIED, decision.message);
  }
  return grpc::Status(grpc::StatusCode::INTERNAL, "unknown authorization outcome");
}

grpc::Status Authorize(const TokenAuth& auth, const grpc::ServerContext& context, Role needed) {
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  std::optional<std::string_view> authorization;
  if (it != metadata.end()) authorization = std::string_view(it->second.data(), it->second.size());
  return ToStatus(auth.Authorize(authorization, needed));
}

}  // namespace visloc::server
