#include "server/auth.h"

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc::server {

TokenAuth TokenAuth::FromFile(const std::string& path) {
  TokenAuth auth;
  for (const TextLine& line : ReadTextLines(path)) {
    const std::vector<std::string> fields = SplitWhitespace(line.text);
    if (fields.empty() || fields[0][0] == '#') continue;
    if (fields.size() != 2 || (fields[1] != "localize" && fields[1] != "admin")) {
      ThrowAtLine(path, line.number, "expected 'TOKEN ROLE' with ROLE localize or admin");
    }
    if (fields[0].size() < 16) ThrowAtLine(path, line.number, "tokens need at least 16 characters");
    auth.roles_[fields[0]] = fields[1] == "admin" ? Role::kAdmin : Role::kLocalize;
  }
  if (auth.roles_.empty()) throw InputError(path + ": no tokens");
  return auth;
}

grpc::Status TokenAuth::Check(const grpc::ServerContext& context, Role needed) const {
  if (!enabled()) return grpc::Status::OK;
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  const std::string prefix = "Bearer ";
  if (it == metadata.end()) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "missing bearer token: give visloc --token TOKEN or $VISLOC_TOKEN (the "
                        "metadata 'authorization: Bearer TOKEN')");
  }
  const std::string value(it->second.data(), it->second.size());
  const auto role =
      value.rfind(prefix, 0) == 0 ? roles_.find(value.substr(prefix.size())) : roles_.end();
  if (role == roles_.end()) return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "unknown token");
  if (static_cast<int>(role->second) < static_cast<int>(needed)) {
    return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                        "this token may localize but not manage maps");
  }
  return grpc::Status::OK;
}

}  // namespace visloc::server
