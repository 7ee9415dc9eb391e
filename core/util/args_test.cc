#include "core/util/args.h"

#include <gtest/gtest.h>

#include <sstream>

#include "core/util/check.h"

namespace visloc {
namespace {

TEST(ArgParserTest, ParsesFlagsSwitchesAndPositionals) {
  std::string out, map;
  int frames = 10;
  double rate = 15.0;
  bool json = false;
  ArgParser parser("visloc test", "A test.");
  parser.AddPositional("MAP", &map, "the map");
  parser.AddFlag("out", &out, "output", /*required=*/true);
  parser.AddFlag("frames", &frames, "frames");
  parser.AddFlag("rate", &rate, "rate");
  parser.AddSwitch("json", &json, "json");
  std::ostringstream help;
  ASSERT_TRUE(parser.Parse({"m.db", "--out", "x", "--frames=42", "--json"}, help));
  EXPECT_EQ(map, "m.db");
  EXPECT_EQ(out, "x");
  EXPECT_EQ(frames, 42);
  EXPECT_DOUBLE_EQ(rate, 15.0);
  EXPECT_TRUE(json);
}

// A flag renamed to say its unit still answers to its former name; --help shows the new one.
TEST(ArgParserTest, AFormerNameStillSetsTheRenamedFlag) {
  double timeout_s = 30.0;
  ArgParser parser("visloc test", "A test.");
  parser.AddFlag("idle-timeout-s", &timeout_s, "seconds");
  parser.AddFormerName("idle-timeout", "idle-timeout-s");
  std::ostringstream help;
  ASSERT_TRUE(parser.Parse({"--idle-timeout", "5"}, help));
  EXPECT_DOUBLE_EQ(timeout_s, 5.0);
  ASSERT_TRUE(parser.Parse({"--idle-timeout-s=7"}, help));
  EXPECT_DOUBLE_EQ(timeout_s, 7.0);
  EXPECT_EQ(parser.Help().find("--idle-timeout "), std::string::npos);
  EXPECT_NE(parser.Help().find("--idle-timeout-s"), std::string::npos);
  EXPECT_THROW(parser.AddFormerName("gone", "never-declared"), CheckError);
}

TEST(ArgParserTest, ReportsBadInputByName) {
  std::string out;
  int frames = 0;
  ArgParser parser("visloc test", "A test.");
  parser.AddFlag("out", &out, "output", /*required=*/true);
  parser.AddFlag("frames", &frames, "frames");
  std::ostringstream help;
  EXPECT_THROW(parser.Parse({"--out", "x", "--bogus"}, help), UsageError);
  EXPECT_THROW(parser.Parse({"--frames", "ten", "--out", "x"}, help), UsageError);
  EXPECT_THROW(parser.Parse({"--out"}, help), UsageError);
  try {
    ArgParser fresh("visloc test", "A test.");
    fresh.AddFlag("out", &out, "output", /*required=*/true);
    fresh.Parse({}, help);
    FAIL() << "expected UsageError";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(), "missing --out");
  }
}

TEST(ArgParserTest, HelpListsEveryOptionAndStopsParsing) {
  std::string out = "default-dir";
  ArgParser parser("visloc test", "Does a test.");
  parser.AddFlag("out", &out, "where to write");
  std::ostringstream help;
  EXPECT_FALSE(parser.Parse({"--help"}, help));
  EXPECT_NE(help.str().find("usage: visloc test"), std::string::npos);
  EXPECT_NE(help.str().find("--out VALUE"), std::string::npos);
  EXPECT_NE(help.str().find("[default: default-dir]"), std::string::npos);
}

// `calibrate --square` showed "[default: 0]" though nothing but a given value will do, and
// `stream --stall-timeout-ms` "[default: 0]" where 0 means 2000 (60000 with --rate 0).
TEST(ArgParserTest, RequiredFlagsShowNoDefaultAndADefaultCanBeSaid) {
  double square_m = 0;
  int stall_ms = 0;
  ArgParser parser("visloc test", "Does a test.");
  parser.AddFlag("square", &square_m, "square side in metres", /*required=*/true);
  parser.AddFlag("stall-timeout-ms", &stall_ms, "no answer this long: reopen");
  parser.SetDefaultText("stall-timeout-ms", "2000; 60000 with --rate 0");
  std::ostringstream help;
  EXPECT_FALSE(parser.Parse({"--help"}, help));
  EXPECT_NE(help.str().find("square side in metres (required)\n"), std::string::npos) << help.str();
  EXPECT_NE(help.str().find("reopen [default: 2000; 60000 with --rate 0]"), std::string::npos);
  EXPECT_EQ(help.str().find("[default: 0]"), std::string::npos) << help.str();
  try {
    parser.Parse({"--stall-timeout-ms", "5"}, help);
    ADD_FAILURE() << "a missing required number was accepted";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(), "missing --square");
  }
}

TEST(ArgParserTest, ListFlagsTakeValuesUpToTheNextFlag) {
  std::vector<std::string> left, right;
  std::string out;
  ArgParser parser("visloc calibrate", "test");
  parser.AddList("left", &left, "left images", /*required=*/true);
  parser.AddList("right", &right, "right images");
  parser.AddFlag("out", &out, "folder");
  std::ostringstream help;
  ASSERT_TRUE(parser.Parse(
      {"--left", "a.png", "b.png", "--out", "x", "--right", "c.png", "--left=d.png"}, help));
  EXPECT_EQ(left, (std::vector<std::string>{"a.png", "b.png", "d.png"}));
  EXPECT_EQ(right, (std::vector<std::string>{"c.png"}));
  EXPECT_EQ(out, "x");
  EXPECT_NE(parser.Help().find("--left VALUE..."), std::string::npos);
  std::vector<std::string> none;
  ArgParser required("visloc calibrate", "test");
  required.AddList("left", &none, "left images", /*required=*/true);
  EXPECT_THROW(required.Parse({}, help), UsageError);
  EXPECT_THROW(required.Parse({"--left"}, help), UsageError);
}

}  // namespace
}  // namespace visloc
