#include "dataset/tum.h"

#include <cmath>
#include <cstdio>

#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc {

// Nanoseconds in an int64 reach 9.22e9 s (year 2262); anything beyond is not a timestamp.
constexpr double kMaxSeconds = 9.0e9;

std::optional<int64_t> ParseSecondsToNs(const std::string& text) {
  const size_t dot = text.find('.');
  const bool plain_decimal = text.find_first_of("eE") == std::string::npos;
  if (plain_decimal && dot != std::string::npos && !StartsWith(text, "-")) {
    const auto seconds = ParseInt64(text.substr(0, dot).empty() ? "0" : text.substr(0, dot));
    std::string fraction = text.substr(dot + 1);
    if (!seconds || *seconds > kMaxSeconds || fraction.size() > 18 ||
        fraction.find_first_not_of("0123456789") != std::string::npos) {
      return std::nullopt;
    }
    fraction = fraction.substr(0, 9);
    fraction.append(9 - fraction.size(), '0');
    return *seconds * 1'000'000'000 + *ParseInt64(fraction);
  }
  const auto seconds = ParseDouble(text);
  if (!seconds || !(std::abs(*seconds) <= kMaxSeconds)) return std::nullopt;
  return SecondsToNs(*seconds);
}

std::string FormatNsAsSeconds(int64_t timestamp_ns) {
  char buffer[48];
  const char* sign = timestamp_ns < 0 ? "-" : "";
  const int64_t magnitude = timestamp_ns < 0 ? -timestamp_ns : timestamp_ns;
  std::snprintf(buffer, sizeof(buffer), "%s%lld.%09lld", sign,
                static_cast<long long>(magnitude / 1'000'000'000),
                static_cast<long long>(magnitude % 1'000'000'000));
  return buffer;
}

Trajectory ReadTum(const std::string& path) {
  Trajectory trajectory;
  for (const DataRow& row : ReadDataRows(path, ' ')) {
    if (row.fields.size() != 8) {
      ThrowAtLine(path, row.line,
                  StrCat("expected 8 fields (timestamp tx ty tz qx qy qz qw), "
                         "found ",
                         row.fields.size()));
    }
    const auto timestamp_ns = ParseSecondsToNs(row.fields[0]);
    if (!timestamp_ns) ThrowAtLine(path, row.line, "bad timestamp '" + row.fields[0] + "'");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = FieldAsDouble(path, row, i + 1);
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      ThrowAtLine(path, row.line, StrCat("quaternion is not unit (norm ", q.norm(), ")"));
    }
    if (!trajectory.empty() && *timestamp_ns <= trajectory.back().timestamp_ns) {
      ThrowAtLine(path, row.line, "timestamps must increase");
    }
    trajectory.push_back(
        {*timestamp_ns, Rigid3d(q.normalized(), Eigen::Vector3d(v[0], v[1], v[2]))});
  }
  return trajectory;
}

std::string TumHeader() { return "# timestamp tx ty tz qx qy qz qw\n"; }

std::string TumLine(const StampedPose& sample) {
  char buffer[256];
  const Eigen::Vector3d& t = sample.pose.translation;
  const Eigen::Quaterniond& q = sample.pose.rotation;
  std::snprintf(buffer, sizeof(buffer), " %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", t.x(), t.y(),
                t.z(), q.x(), q.y(), q.z(), q.w());
  return FormatNsAsSeconds(sample.timestamp_ns) + buffer;
}

void WriteTum(const std::string& path, const Trajectory& trajectory) {
  std::string out = TumHeader();
  for (const StampedPose& sample : trajectory) out += TumLine(sample);
  WriteFileAtomically(path, out);
}

}  // namespace visloc
