#include "core/util/text_file.h"

#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc {

std::vector<TextLine> ReadTextLines(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(StrCat(path, ": cannot open file"));
  std::vector<TextLine> lines;
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    lines.push_back({number, std::move(text)});
  }
  return lines;
}

std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(StrCat(path, ": cannot open file"));
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) throw InputError(StrCat(path, ": read error"));
  return bytes.str();
}

std::vector<DataRow> ReadDataRows(const std::string& path, char delimiter) {
  std::vector<DataRow> rows;
  for (const TextLine& line : ReadTextLines(path)) {
    const std::string_view trimmed = Trim(line.text);
    if (trimmed.empty() || trimmed.front() == '#') continue;
    rows.push_back(
        {line.number, delimiter == ' ' ? SplitWhitespace(trimmed) : Split(trimmed, delimiter)});
  }
  return rows;
}

void ThrowAtLine(const std::string& path, int line, const std::string& message) {
  throw InputError(StrCat(path, ":", line, ": ", message));
}

void RequireFieldCount(const std::string& path, const DataRow& row, size_t count) {
  if (row.fields.size() < count) {
    ThrowAtLine(path, row.line, StrCat("expected ", count, " fields, found ", row.fields.size()));
  }
}

double FieldAsDouble(const std::string& path, const DataRow& row, size_t index) {
  RequireFieldCount(path, row, index + 1);
  const auto value = ParseDouble(row.fields[index]);
  if (!value) {
    ThrowAtLine(path, row.line,
                StrCat("field ", index + 1, " is not a number: '", row.fields[index], "'"));
  }
  return *value;
}

int64_t FieldAsInt64(const std::string& path, const DataRow& row, size_t index) {
  RequireFieldCount(path, row, index + 1);
  const auto value = ParseInt64(row.fields[index]);
  if (!value) {
    ThrowAtLine(path, row.line,
                StrCat("field ", index + 1, " is not an integer: '", row.fields[index], "'"));
  }
  return *value;
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  const std::string temp_path = path + ".tmp";
  {
    std::ofstream out(temp_path, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(StrCat(path, ": cannot write file"));
    out << contents;
    out.flush();
    if (!out) throw InputError(StrCat(path, ": write failed"));
  }
  if (std::rename(temp_path.c_str(), path.c_str()) != 0) {
    std::remove(temp_path.c_str());
    throw InputError(StrCat(path, ": cannot rename temporary file into place"));
  }
}

}  // namespace visloc
