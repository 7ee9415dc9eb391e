#include "ros/bag/stereo_pairer.h"

#include <algorithm>
#include <cstdlib>

namespace visloc::bag {

StereoPairer::StereoPairer(int64_t tolerance_ns, EmitFn emit)
    : tolerance_ns_(tolerance_ns), emit_(std::move(emit)) {}

void StereoPairer::Add(std::deque<Pending>& side, int64_t stamp_ns, cv::Mat grey) {
  if (stamp_ns <= last_emitted_ns_) {
    ++stats_.out_of_order;
    return;
  }
  // Keep the queue sorted by stamp (bags are in recording order; stamps may interleave).
  auto at = std::upper_bound(side.begin(), side.end(), stamp_ns,
                             [](int64_t t, const Pending& p) { return t < p.stamp_ns; });
  side.insert(at, Pending{stamp_ns, std::move(grey)});
  Drain(false);
  // The other camera is silent (a topic that stopped, or never started): memory stays bounded.
  while (side.size() > kMaxPending) DropFront(side);
}

void StereoPairer::DropFront(std::deque<Pending>& side) {
  ++(&side == &left_ ? stats_.unpaired_left : stats_.unpaired_right);
  side.pop_front();
}

void StereoPairer::Drain(bool final) {
  while (!left_.empty() && !right_.empty()) {
    const int64_t l = left_.front().stamp_ns;
    const int64_t r = right_.front().stamp_ns;
    if (l < r - tolerance_ns_) {  // No right image to come can be close enough to l.
      DropFront(left_);
      continue;
    }
    if (r < l - tolerance_ns_) {
      DropFront(right_);
      continue;
    }
    // Both within tolerance: pair them unless a later image of one side fits the other better.
    // Until that later image has arrived, wait (unless the stream is over).
    const bool right_may_improve = right_.size() < 2 && !final && r < l;
    const bool left_may_improve = left_.size() < 2 && !final && l < r;
    if (right_may_improve || left_may_improve) return;
    if (right_.size() >= 2 && std::llabs(right_[1].stamp_ns - l) < std::llabs(r - l)) {
      DropFront(right_);
      continue;
    }
    if (left_.size() >= 2 && std::llabs(left_[1].stamp_ns - r) < std::llabs(l - r)) {
      DropFront(left_);
      continue;
    }
    stats_.max_offset_ns = std::max<int64_t>(stats_.max_offset_ns, std::llabs(l - r));
    ++stats_.paired;
    last_emitted_ns_ = std::max(l, r);
    emit_(l, left_.front().grey, right_.front().grey);
    left_.pop_front();
    right_.pop_front();
  }
}

void StereoPairer::Finish() {
  Drain(true);
  stats_.unpaired_left += static_cast<int>(left_.size());
  stats_.unpaired_right += static_cast<int>(right_.size());
  left_.clear();
  right_.clear();
}

}  // namespace visloc::bag
