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

std::optional<Role> TokenAuth::RoleOf(std::string_view token) const {
  const auto it = roles_.find(token);
  if (it == roles_.end()) return std::nullopt;
  return it->second;
}

AuthDecision TokenAuth::Authorize(const std::optional<std::string_view>& authorization,
                                  Role needed) const {
  using Outcome = AuthDecision::Outcome;
  if (!enabled()) return {};
  if (!authorization) {
    return {Outcome::kUnauthenticated,
            "missing bearer token: give visloc --token TOKEN or $VISLOC_TOKEN (the "
            "metadata 'authorization: Bearer TOKEN')"};
  }
  constexpr std::string_view kPrefix = "Bearer ";
  const std::optional<Role> role = authorization->substr(0, kPrefix.size()) == kPrefix
                                       ? RoleOf(authorization->substr(kPrefix.size()))
                                       : std::nullopt;
  if (!role) return {Outcome::kUnauthenticated, "unknown token"};
  if (static_cast<int>(*role) < static_cast<int>(needed)) {
    return {Outcome::kPermissionDenied, "this token may localize but not manage maps"};
  }
  return {};
}

}  // namespace visloc::server
