#include "core/util/arrival_predictor.h"

#include <chrono>

#include <gtest/gtest.h>

namespace visloc {
namespace {

using std::chrono::microseconds;
using Clock = ArrivalPredictor::Clock;

double MsFrom(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

Clock::time_point At(double ms) {
  return Clock::time_point(microseconds(static_cast<int64_t>(ms * 1000.0)));
}

TEST(ArrivalPredictorTest, NothingIsPredictedFromFewerThanThreeIntervals) {
  ArrivalPredictor predictor;
  for (int i = 0; i < 3; ++i) {
    predictor.Observe(At(1000.0 + i * 66.7));
    EXPECT_FALSE(predictor.Next()) << i + 1 << " arrivals";
  }
  predictor.Observe(At(1000.0 + 3 * 66.7));
  EXPECT_TRUE(predictor.Next());
}

TEST(ArrivalPredictorTest, ASteadyCameraIsExpectedOnePeriodOnWithTheNarrowestWindow) {
  ArrivalPredictor predictor;
  for (int i = 0; i < 20; ++i) predictor.Observe(At(1000.0 + i * 66.7));
  const auto next = predictor.Next();
  ASSERT_TRUE(next);
  EXPECT_NEAR(MsFrom(At(1000.0 + 19 * 66.7), next->when), 66.7, 0.002);
  EXPECT_EQ(next->lead, microseconds(1000));  // Options::min_window_ms.
  EXPECT_EQ(next->grace, microseconds(1000));
}

TEST(ArrivalPredictorTest, AJitteryLinkWidensTheWindowUpToItsCap) {
  ArrivalPredictor predictor;
  // 49.8 and 50.2 ms in turn: the median interval one of them, the median absolute deviation
  // 0.4 ms, the window 6 x 0.4 = 2.4 ms a side.
  double t = 0.0;
  for (int i = 0; i < 9; ++i) predictor.Observe(At(t += (i % 2 ? 50.2 : 49.8)));
  auto next = predictor.Next();
  ASSERT_TRUE(next);
  EXPECT_NEAR(next->lead.count(), 2400, 1);
  // +- 4 ms: capped at 3 ms a side.
  for (int i = 0; i < 9; ++i) predictor.Observe(At(t += (i % 2 ? 54.0 : 46.0)));
  next = predictor.Next();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->lead, microseconds(3000));
  EXPECT_EQ(next->grace, microseconds(3000));
}

TEST(ArrivalPredictorTest, OnePauseDoesNotMoveThePrediction) {
  ArrivalPredictor predictor;
  double t = 0.0;
  for (int i = 0; i < 8; ++i) predictor.Observe(At(t += 66.7));
  predictor.Observe(At(t += 2000.0));  // The robot stopped sending for 2 s.
  const auto next = predictor.Next();
  ASSERT_TRUE(next);
  EXPECT_NEAR(MsFrom(At(t), next->when), 66.7, 0.002);
}

TEST(ArrivalPredictorTest, BackToBackFramesKeepTheWindowWithinAQuarterOfTheInterval) {
  ArrivalPredictor predictor;
  for (int i = 0; i < 9; ++i) predictor.Observe(At(i * 1.0));  // 1 ms apart.
  const auto next = predictor.Next();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->lead, microseconds(250));
}

}  // namespace
}  // namespace visloc
