#pragma once
// Strict string helpers: parsers reject trailing garbage and empty fields instead of
// returning 0, so malformed dataset rows are reported rather than silently misread.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <string_view>
#include <vector>

namespace visloc {

std::string_view Trim(std::string_view text);
// Splits on `delimiter`; keeps empty fields ("a,,b" has three). Each field is trimmed.
std::vector<std::string> Split(std::string_view text, char delimiter);
// Splits on runs of spaces and tabs; never yields empty fields.
std::vector<std::string> SplitWhitespace(std::string_view text);
bool StartsWith(std::string_view text, std::string_view prefix);
bool EndsWith(std::string_view text, std::string_view suffix);
std::string ToLower(std::string_view text);

// Return std::nullopt unless the whole (trimmed) text is a valid finite number.
std::optional<double> ParseDouble(std::string_view text);
std::optional<int64_t> ParseInt64(std::string_view text);
// "AxB" (either case of x) with both integers in [min, max]: "320x240", "9x6". Nothing on
// any other text.
std::optional<std::pair<int, int>> ParseDimensions(const std::string& text, int min, int max);

// Formats a double with `digits` decimals ("%.*f").
std::string FormatFixed(double value, int digits);

}  // namespace visloc
