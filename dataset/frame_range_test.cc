#include "dataset/frame_range.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/util/check.h"

namespace visloc {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

TEST(FrameRangeTest, ACountIsTheFirstFramesAsBefore) {
  EXPECT_THAT(SelectedFrames(ParseFrameRange("3"), 10), ElementsAre(0, 1, 2));
  EXPECT_TRUE(ParseFrameRange("0").all());
  EXPECT_TRUE(ParseFrameRange("").all());
  EXPECT_THAT(SelectedFrames(ParseFrameRange("30"), 4), ElementsAre(0, 1, 2, 3));
}

TEST(FrameRangeTest, SlicesSelectHalvesAndEveryOtherFrame) {
  EXPECT_THAT(SelectedFrames(ParseFrameRange("5:8"), 10), ElementsAre(5, 6, 7));
  EXPECT_THAT(SelectedFrames(ParseFrameRange("7:"), 10), ElementsAre(7, 8, 9));
  EXPECT_THAT(SelectedFrames(ParseFrameRange("0:10:2"), 10), ElementsAre(0, 2, 4, 6, 8));
  EXPECT_THAT(SelectedFrames(ParseFrameRange("1::3"), 10), ElementsAre(1, 4, 7));
}

TEST(FrameRangeTest, MalformedSelectionsAreNamed) {
  for (const char* text : {"x", "-2", "5:3", "1:2:0", "1:2:3:4", "a:3"}) {
    try {
      ParseFrameRange(text);
      ADD_FAILURE() << text << " was accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(std::string("'") + text + "'"));
    }
  }
}

TEST(FrameRangeTest, SelectingKeepsTheChosenFramesAndRefusesAnEmptySelection) {
  Dataset dataset;
  dataset.root = "seq";
  for (int i = 0; i < 6; ++i) dataset.frames.push_back({i * 100, "l" + std::to_string(i), ""});
  const Dataset odd = SelectFrames(dataset, ParseFrameRange("1::2"));
  ASSERT_EQ(odd.frames.size(), 3u);
  EXPECT_EQ(odd.frames[2].timestamp_ns, 500);
  EXPECT_THROW(SelectFrames(dataset, ParseFrameRange("7:9")), InputError);
}

}  // namespace
}  // namespace visloc
