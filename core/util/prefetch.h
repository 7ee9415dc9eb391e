#pragma once
// Items made ahead on one thread while the caller works on earlier ones: a map build prepares
// frames (decoding, features, rectification) while its mapping thread tracks and adjusts. The
// mapping thread's cost per frame is uneven (a keyframe's local adjustment takes several frames'
// time), so one frame ahead leaves the preparing thread idle through every adjustment and the
// mapping thread waiting after it; a few frames ahead absorb the bursts.
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "core/util/check.h"

namespace visloc {

// make(0), make(1), ..., make(count - 1), each made once, in order, on one thread of its own,
// at most `depth` of them made and not yet taken. Next() returns them in order; an exception
// thrown by make(i) is rethrown by the Next() that would have returned it (nothing after it is
// made). The destructor stops making and waits for the item in progress.
template <typename T>
class OrderedPrefetch {
 public:
  OrderedPrefetch(int count, int depth, std::function<T(int)> make)
      : count_(count), depth_(depth), make_(std::move(make)) {
    VISLOC_CHECK(count >= 0 && depth >= 1, "OrderedPrefetch: count >= 0, depth >= 1");
    thread_ = std::thread([this] { Run(); });
  }
  ~OrderedPrefetch() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopped_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  OrderedPrefetch(const OrderedPrefetch&) = delete;
  OrderedPrefetch& operator=(const OrderedPrefetch&) = delete;

  T Next() {
    std::unique_lock<std::mutex> lock(mutex_);
    VISLOC_CHECK(taken_ < count_, "OrderedPrefetch: every item was taken");
    changed_.wait(lock, [this] { return !ready_.empty() || failure_; });
    if (ready_.empty()) std::rethrow_exception(failure_);
    T item = std::move(ready_.front());
    ready_.pop_front();
    ++taken_;
    lock.unlock();
    changed_.notify_all();
    return item;
  }

 private:
  void Run() {
    for (int i = 0; i < count_; ++i) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        changed_.wait(lock,
                      [this] { return stopped_ || static_cast<int>(ready_.size()) < depth_; });
        if (stopped_) return;
      }
      std::optional<T> item;
      try {
        item.emplace(make_(i));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex_);
        failure_ = std::current_exception();
        changed_.notify_all();
        return;
      }
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        ready_.push_back(std::move(*item));
      }
      changed_.notify_all();
    }
  }

  const int count_, depth_;
  const std::function<T(int)> make_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<T> ready_;  // Made, in order, not yet taken.
  int taken_ = 0;
  std::exception_ptr failure_;
  bool stopped_ = false;
  std::thread thread_;  // Last: started once the rest is built.
};

}  // namespace visloc
