#pragma once
// Line-oriented reading of text data files (CSV, TUM, KITTI) with errors that name the file
// and the 1-based line, which is what a user needs to fix a malformed dataset.

#include <functional>
#include <string>
#include <vector>

namespace visloc {

struct TextLine {
  int number = 0;    // 1-based line number in the file.
  std::string text;  // Without the line terminator (\n or \r\n).
};

// Reads all lines of `path`. Throws InputError naming the file if it cannot be opened.
std::vector<TextLine> ReadTextLines(const std::string& path);

// Reads the data lines of a comma- or space-separated file: blank lines and lines starting
// with '#' are skipped. `delimiter` == ' ' splits on runs of whitespace.
struct DataRow {
  int line = 0;
  std::vector<std::string> fields;
};
std::vector<DataRow> ReadDataRows(const std::string& path, char delimiter);

// Throws InputError "<path>:<line>: <message>".
[[noreturn]] void ThrowAtLine(const std::string& path, int line, const std::string& message);

// Parses field `index` of `row` as a number or throws InputError naming file, line and column.
double FieldAsDouble(const std::string& path, const DataRow& row, size_t index);
int64_t FieldAsInt64(const std::string& path, const DataRow& row, size_t index);
// Throws unless the row has at least `count` fields.
void RequireFieldCount(const std::string& path, const DataRow& row, size_t count);

// The whole file as bytes (images, certificates, map files). Throws InputError naming the file
// when it cannot be read.
std::string ReadFileBytes(const std::string& path);

// Writes `contents` to `path` atomically (temporary file + rename), so a reader never sees a
// half-written file. Throws InputError when the file cannot be written.
void WriteFileAtomically(const std::string& path, const std::string& contents);

}  // namespace visloc
