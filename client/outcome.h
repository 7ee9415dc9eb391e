#pragma once
// What a verb that changes something (upload, download, delete, rename, export) reports: one
// sentence for people, or with --json one object {"ok":true, fields...}. A failure is reported
// by main() as {"ok":false,"command":...,"error":...,"exit_code":...}, so a script that reads
// stdout of any verb given --json gets one JSON object either way.

#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace visloc::cli {

using OutcomeFields =
    std::vector<std::pair<std::string, std::variant<std::string, int64_t, double>>>;

// Prints `sentence` (a newline is added), or the fields as JSON when `json`. Returns 0.
int PrintOutcome(bool json, const std::string& sentence, const OutcomeFields& fields);

}  // namespace visloc::cli
