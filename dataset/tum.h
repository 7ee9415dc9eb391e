#pragma once
// TUM trajectory files: one pose a line, "timestamp tx ty tz qx qy qz qw", timestamp in
// seconds (float), '#' comments. Timestamps are kept exactly: "1403636579.763555584" reads as
// that many nanoseconds, not via a double that would lose the last digits.

#include <string>

#include "core/geometry/trajectory.h"

namespace visloc {

// Throws InputError "<path>:<line>: ..." for malformed rows, non-unit quaternions (norm off
// by more than 1e-3) and timestamps that do not increase.
Trajectory ReadTum(const std::string& path);
// Writes atomically with nanosecond timestamps and 9-digit poses.
void WriteTum(const std::string& path, const Trajectory& trajectory);

// "12.5" -> 12500000000. Decimal notation is parsed exactly; other forms via double.
std::optional<int64_t> ParseSecondsToNs(const std::string& text);
std::string FormatNsAsSeconds(int64_t timestamp_ns);
// The header comment and one pose line ("timestamp tx ty tz qx qy qz qw\n") of a TUM file, for
// writers that append as poses arrive.
std::string TumHeader();
std::string TumLine(const StampedPose& sample);

}  // namespace visloc
