#pragma once
// Pairs left and right images into stereo frames by header stamp, as they stream out of a bag
// (in recording order, which may differ slightly from stamp order). An image is paired with
// the other camera's image closest in time when that is within `tolerance_ns`; images with no
// partner are counted, never paired twice. Only a few images are held at a time: an image is
// decided once the other camera's stream has moved past its stamp by more than the tolerance.

#include <cstdint>
#include <deque>
#include <functional>

#include <opencv2/core.hpp>

namespace visloc::bag {

struct PairingStats {
  int paired = 0;
  int unpaired_left = 0;
  int unpaired_right = 0;
  int out_of_order = 0;     // Images stamped before a frame already written: left out.
  int64_t max_offset_ns = 0;  // Largest stamp difference within a pair.
};

class StereoPairer {
 public:
  // `emit(stamp_ns, left, right)` receives pairs in increasing stamp order (the left stamp).
  using EmitFn = std::function<void(int64_t, const cv::Mat&, const cv::Mat&)>;
  StereoPairer(int64_t tolerance_ns, EmitFn emit);

  void AddLeft(int64_t stamp_ns, cv::Mat grey) { Add(left_, stamp_ns, std::move(grey)); }
  void AddRight(int64_t stamp_ns, cv::Mat grey) { Add(right_, stamp_ns, std::move(grey)); }
  // Pairs what can still be paired and counts the rest as unpaired.
  void Finish();

  const PairingStats& stats() const { return stats_; }

 private:
  struct Pending {
    int64_t stamp_ns;
    cv::Mat grey;
  };
  void Add(std::deque<Pending>& side, int64_t stamp_ns, cv::Mat grey);
  // Decides what the queues' fronts allow; `final` decides everything.
  void Drain(bool final);
  void DropFront(std::deque<Pending>& side);

  static constexpr size_t kMaxPending = 64;  // Images held while the other camera is silent.

  int64_t tolerance_ns_;
  EmitFn emit_;
  std::deque<Pending> left_;
  std::deque<Pending> right_;
  int64_t last_emitted_ns_ = INT64_MIN;
  PairingStats stats_;
};

}  // namespace visloc::bag
