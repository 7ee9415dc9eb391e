#include "core/util/strings.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace visloc {

std::string_view Trim(std::string_view text) {
  size_t begin = 0;
  size_t end = text.size();
  while (begin < end && std::isspace(static_cast<unsigned char>(text[begin]))) ++begin;
  while (end > begin && std::isspace(static_cast<unsigned char>(text[end - 1]))) --end;
  return text.substr(begin, end - begin);
}

std::vector<std::string> Split(std::string_view text, char delimiter) {
  std::vector<std::string> fields;
  size_t start = 0;
  while (true) {
    const size_t pos = text.find(delimiter, start);
    fields.emplace_back(
        Trim(text.substr(start, pos == std::string_view::npos ? pos : pos - start)));
    if (pos == std::string_view::npos) break;
    start = pos + 1;
  }
  return fields;
}

std::vector<std::string> SplitWhitespace(std::string_view text) {
  std::vector<std::string> fields;
  size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r')) ++i;
    size_t j = i;
    while (j < text.size() && text[j] != ' ' && text[j] != '\t' && text[j] != '\r') ++j;
    if (j > i) fields.emplace_back(text.substr(i, j - i));
    i = j;
  }
  return fields;
}

bool StartsWith(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

bool EndsWith(std::string_view text, std::string_view suffix) {
  return text.size() >= suffix.size() && text.substr(text.size() - suffix.size()) == suffix;
}

std::string ToLower(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::optional<double> ParseDouble(std::string_view text) {
  const std::string trimmed(Trim(text));
  if (trimmed.empty()) return std::nullopt;
  // strtod rather than from_chars: GCC 12's from_chars for double is fine, but strtod also
  // accepts forms like "1e-3" and "+1.5" that calibration files contain.
  char* end = nullptr;
  const double value = std::strtod(trimmed.c_str(), &end);
  if (end != trimmed.c_str() + trimmed.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

std::optional<int64_t> ParseInt64(std::string_view text) {
  const std::string_view trimmed = Trim(text);
  if (trimmed.empty()) return std::nullopt;
  int64_t value = 0;
  const char* first = trimmed.data();
  if (*first == '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, trimmed.data() + trimmed.size(), value);
  if (ec != std::errc() || ptr != trimmed.data() + trimmed.size()) return std::nullopt;
  return value;
}

std::string FormatFixed(double value, int digits) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", digits, value);
  return buffer;
}

std::optional<std::pair<int, int>> ParseDimensions(const std::string& text, int min, int max) {
  const std::vector<std::string> parts = Split(ToLower(text), 'x');
  if (parts.size() != 2) return std::nullopt;
  const auto a = ParseInt64(parts[0]), b = ParseInt64(parts[1]);
  if (!a || !b || *a < min || *b < min || *a > max || *b > max) return std::nullopt;
  return std::make_pair(static_cast<int>(*a), static_cast<int>(*b));
}

}  // namespace visloc
