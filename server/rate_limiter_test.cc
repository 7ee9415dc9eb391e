#include "server/rate_limiter.h"

#include <gtest/gtest.h>

namespace visloc::server {
namespace {

using std::chrono::milliseconds;

TEST(FrameRateLimiterTest, AdmitsTheRateWithOneSecondOfBurst) {
  FrameRateLimiter limiter(10.0);
  const auto start = FrameRateLimiter::Clock::time_point() + std::chrono::hours(1);
  // A burst of 15 frames at once: the bucket holds one second's worth (10).
  int admitted = 0;
  for (int i = 0; i < 15; ++i) admitted += limiter.Admit(start);
  EXPECT_EQ(admitted, 10);
  // Then 30 Hz for 3 s: 10 Hz of it gets through (one frame per 100 ms refilled).
  admitted = 0;
  for (int i = 1; i <= 90; ++i) admitted += limiter.Admit(start + milliseconds(i * 1000 / 30));
  EXPECT_NEAR(admitted, 30, 1);
  // A client that keeps to the rate is never refused.
  FrameRateLimiter steady(15.0);
  for (int i = 0; i < 300; ++i) {
    ASSERT_TRUE(steady.Admit(start + milliseconds(i * 1000 / 15))) << "frame " << i;
  }
}

TEST(FrameRateLimiterTest, ZeroMeansNoLimit) {
  FrameRateLimiter limiter(0.0);
  const auto now = FrameRateLimiter::Clock::now();
  for (int i = 0; i < 1000; ++i) ASSERT_TRUE(limiter.Admit(now));
}

}  // namespace
}  // namespace visloc::server
