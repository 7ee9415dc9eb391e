#include "core/util/strings.h"

#include <gtest/gtest.h>

namespace visloc {
namespace {

TEST(StringsTest, SplitKeepsEmptyFieldsAndTrims) {
  const auto fields = Split(" a, ,b ", ',');
  ASSERT_EQ(fields.size(), 3u);
  EXPECT_EQ(fields[0], "a");
  EXPECT_EQ(fields[1], "");
  EXPECT_EQ(fields[2], "b");
}

TEST(StringsTest, SplitWhitespaceSkipsRuns) {
  const auto fields = SplitWhitespace("  1.0\t 2  3\r");
  ASSERT_EQ(fields.size(), 3u);
  EXPECT_EQ(fields[2], "3");
}

TEST(StringsTest, ParseDoubleIsStrict) {
  EXPECT_DOUBLE_EQ(*ParseDouble(" 1.5e-3 "), 1.5e-3);
  EXPECT_DOUBLE_EQ(*ParseDouble("+2"), 2.0);
  EXPECT_FALSE(ParseDouble("1.5x"));
  EXPECT_FALSE(ParseDouble(""));
  EXPECT_FALSE(ParseDouble("nan"));
  EXPECT_FALSE(ParseDouble("inf"));
}

TEST(StringsTest, ParseInt64IsStrict) {
  EXPECT_EQ(*ParseInt64("1403636579763555584"), 1403636579763555584LL);
  EXPECT_EQ(*ParseInt64("-7"), -7);
  EXPECT_FALSE(ParseInt64("12.5"));
  EXPECT_FALSE(ParseInt64("99999999999999999999"));
  EXPECT_FALSE(ParseInt64("abc"));
}

}  // namespace
}  // namespace visloc
