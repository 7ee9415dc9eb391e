#include "core/util/arrival_predictor.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace visloc {
namespace {

double MedianOf(std::vector<double> values) {
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

}  // namespace

void ArrivalPredictor::Observe(Clock::time_point arrival) {
  arrivals_.push_back(arrival);
  while (static_cast<int>(arrivals_.size()) > std::max(2, options_.history)) arrivals_.pop_front();
}

std::optional<ArrivalPredictor::Expectation> ArrivalPredictor::Next() const {
  const int intervals = static_cast<int>(arrivals_.size()) - 1;
  if (intervals < std::max(1, options_.min_intervals)) return std::nullopt;
  std::vector<double> interval_ms;
  for (size_t i = 1; i < arrivals_.size(); ++i) {
    interval_ms.push_back(
        std::chrono::duration<double, std::milli>(arrivals_[i] - arrivals_[i - 1]).count());
  }
  const double median_ms = MedianOf(interval_ms);
  std::vector<double> deviation_ms;
  for (const double ms : interval_ms) deviation_ms.push_back(std::abs(ms - median_ms));
  const double spread_ms = MedianOf(deviation_ms);
  const double window_ms =
      std::min({std::max(options_.min_window_ms, options_.spread_gain * spread_ms),
                options_.max_window_ms, options_.max_window_fraction * median_ms});
  const auto to_us = [](double ms) {
    return std::chrono::microseconds(static_cast<int64_t>(std::llround(ms * 1000.0)));
  };
  Expectation next;
  next.when = arrivals_.back() + to_us(median_ms);
  next.lead = to_us(window_ms);
  next.grace = to_us(window_ms);
  return next;
}

}  // namespace visloc
