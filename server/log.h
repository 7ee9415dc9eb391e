#pragma once
// Structured server logs: one line per event on stderr, "ts=... event=NAME key=value ...", with
// values quoted when they contain spaces, so that grep and log shippers can parse them.

#include <string>
#include <utility>
#include <vector>

namespace visloc::server {

void Log(const std::string& event, const std::vector<std::pair<std::string, std::string>>& fields);

}  // namespace visloc::server
