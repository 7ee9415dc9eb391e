#include "core/util/text_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/util/check.h"
#include "core/util/temp_dir.h"

namespace visloc {
namespace {

// Files live in one scratch folder removed when the test binary exits.
std::string WriteTemp(const std::string& name, const std::string& contents) {
  static const TempDir dir("visloc_text_file_test");
  const std::string path = dir.File(name);
  std::ofstream(path) << contents;
  return path;
}

TEST(TextFileTest, SkipsCommentsAndBlankLinesKeepingLineNumbers) {
  const std::string path = WriteTemp("rows.csv", "#header\n\n1,2\r\n3, x\n");
  const auto rows = ReadDataRows(path, ',');
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].line, 3);
  EXPECT_EQ(rows[1].line, 4);
  EXPECT_DOUBLE_EQ(FieldAsDouble(path, rows[0], 1), 2.0);
  try {
    FieldAsDouble(path, rows[1], 1);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ":4: field 2 is not a number: 'x'");
  }
}

TEST(TextFileTest, MissingFileIsNamed) {
  try {
    ReadTextLines("/nonexistent/file.csv");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/file.csv: cannot open file");
  }
}

TEST(TextFileTest, AtomicWriteReplacesContents) {
  const std::string path = WriteTemp("atomic.txt", "old");
  WriteFileAtomically(path, "new contents\n");
  const auto lines = ReadTextLines(path);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].text, "new contents");
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

}  // namespace
}  // namespace visloc
