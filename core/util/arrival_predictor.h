#pragma once
// When the next event of a periodic stream comes: a robot's frames arrive at its camera's rate,
// give or take the link's jitter. A rig session's helper threads sleep between frames, and on a
// virtual machine a sleeping thread on an idle core starts 0.1-0.2 ms after it is woken (the
// host has to bring the core back), which at 320x240 is a fifth of a frame. Knowing when the
// next frame is due, the helpers wake themselves a little before it (WorkerPool::ExpectJob).

#include <chrono>
#include <deque>
#include <optional>

namespace visloc {

class ArrivalPredictor {
 public:
  using Clock = std::chrono::steady_clock;

  struct Options {
    int history = 9;             // Arrivals kept: the median of the last history - 1 intervals.
    int min_intervals = 3;       // No prediction from fewer.
    double min_window_ms = 1.0;  // The window's half-width at least: a wake's own latency.
    double max_window_ms = 3.0;  // At most: what a missed prediction may spin, per side.
    double max_window_fraction = 0.25;  // And at most this share of the interval.
    double spread_gain = 6.0;           // The half-width: this many median absolute deviations.
    // (Through the server at 15 fps, 3 of them and 0.6 ms at least met the frame 70% of the
    // time: the link's jitter has long tails; 6 and 1 ms: 90-98% in a trial run, 52-97% (median
    // 81%) in 8 sessions at 2af0c8e, as their session_end lines count helper_wakes_met.)
  };

  // The next arrival's prediction: due at `when`, expected within [when - lead, when + grace].
  struct Expectation {
    Clock::time_point when;
    std::chrono::microseconds lead{0};
    std::chrono::microseconds grace{0};
  };

  ArrivalPredictor() = default;
  explicit ArrivalPredictor(const Options& options) : options_(options) {}

  // An arrival, in increasing time.
  void Observe(Clock::time_point arrival);
  // The next arrival after the last one observed: its median interval later, with a window of
  // the intervals' spread; none until min_intervals intervals have been seen.
  std::optional<Expectation> Next() const;

 private:
  Options options_;
  std::deque<Clock::time_point> arrivals_;
};

}  // namespace visloc
