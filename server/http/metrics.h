#pragma once
// The server's state in the Prometheus text exposition format (version 0.0.4), from one
// ServerStatus snapshot: what `visloc sessions` and the operator page read too. Names follow
// Prometheus' conventions (visloc_ prefix, base units, _total for counters); labels are bounded
// (map, status, result), never robot ids or times.

#include <string>

#include "server/server_status.h"

namespace visloc::server {

std::string PrometheusText(const ServerStatus& status, const std::string& version);

}  // namespace visloc::server
