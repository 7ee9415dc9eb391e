#pragma once
// Bearer-token authorization with two roles (product.md): robots may localize; admins may also
// manage maps. Tokens come from a file, one "TOKEN ROLE" pair a line ('#' comments), and reach
// the server as the "authorization: Bearer TOKEN" metadata of each call. Without a tokens file
// every call is allowed (the server then listens on loopback only unless told otherwise).

#include <map>
#include <string>

#include <grpcpp/grpcpp.h>

namespace visloc::server {

enum class Role { kLocalize = 1, kAdmin = 2 };

class TokenAuth {
 public:
  TokenAuth() = default;  // Disabled: everything allowed.
  // Throws InputError naming the file and line of a malformed entry.
  static TokenAuth FromFile(const std::string& path);

  bool enabled() const { return !roles_.empty(); }
  // OK, UNAUTHENTICATED (no or unknown token) or PERMISSION_DENIED (role too weak).
  grpc::Status Check(const grpc::ServerContext& context, Role needed) const;

 private:
  std::map<std::string, Role> roles_;
};

}  // namespace visloc::server
