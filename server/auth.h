#pragma once
// Bearer-token authorization with two roles (product.md): robots may localize; admins may also
// manage maps. Tokens come from a file, one "TOKEN ROLE" pair a line ('#' comments), and reach
// the server in each call's "authorization: Bearer TOKEN" header (gRPC metadata, or an HTTP
// header: nothing here knows the transport; server/rpc.h maps a decision to a gRPC status).
// Without a tokens file every call is allowed (the server then listens on loopback only unless
// told otherwise).

#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace visloc::server {

enum class Role { kLocalize = 1, kAdmin = 2 };

// What a caller may do, and if not, why (a message for the caller).
struct AuthDecision {
  enum class Outcome { kAllowed, kUnauthenticated, kPermissionDenied };
  Outcome outcome = Outcome::kAllowed;
  std::string message;
  bool allowed() const { return outcome == Outcome::kAllowed; }
};

class TokenAuth {
 public:
  TokenAuth() = default;  // Disabled: everything allowed.
  // Throws InputError naming the file and line of a malformed entry.
  static TokenAuth FromFile(const std::string& path);

  bool enabled() const { return !roles_.empty(); }
  // The token's role; none for an unknown token.
  std::optional<Role> RoleOf(std::string_view token) const;
  // `authorization`: the header's value ("Bearer TOKEN"), none when the call carried none.
  AuthDecision Authorize(const std::optional<std::string_view>& authorization, Role needed) const;

 private:
  std::map<std::string, Role, std::less<>> roles_;
};

}  // namespace visloc::server
