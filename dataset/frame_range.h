#pragma once
// A selection of a sequence's frames, as the command line names it: "N" is the first N frames
// (what `--frames N` always meant), "BEGIN:END" the frames BEGIN..END-1 and "BEGIN:END:STEP"
// every STEP-th of them (Python's slice; END may be left out for "to the last frame"). How a
// map of the first half of a recording is built and its second half queried, or a map of the
// even frames and the odd ones localized in it.

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "dataset/dataset.h"

namespace visloc {

struct FrameRange {
  size_t begin = 0;
  size_t end = std::numeric_limits<size_t>::max();  // Past the last selected frame.
  size_t step = 1;
  bool all() const { return begin == 0 && end == std::numeric_limits<size_t>::max() && step == 1; }
};

// Parses "N", "BEGIN:END" or "BEGIN:END:STEP" ("" and "0" select every frame). Throws InputError
// naming the text when it is not one of these, or END <= BEGIN, or STEP < 1.
FrameRange ParseFrameRange(const std::string& text);

// The indices of the selected frames among `count` (a range past the end is cut at the end).
std::vector<size_t> SelectedFrames(const FrameRange& range, size_t count);

// The dataset with only the selected frames (ground truth, odometry and IMU are kept whole: they
// are looked up by time). Throws InputError when the selection holds no frame.
Dataset SelectFrames(Dataset dataset, const FrameRange& range);

}  // namespace visloc
