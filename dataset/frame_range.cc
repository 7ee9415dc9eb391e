#include "dataset/frame_range.h"

#include <optional>

#include "core/util/check.h"
#include "core/util/strings.h"

namespace visloc {
namespace {

std::optional<size_t> ParseIndex(const std::string& text) {
  const std::optional<int64_t> value = ParseInt64(text);
  if (!value || *value < 0) return std::nullopt;
  return static_cast<size_t>(*value);
}

}  // namespace

FrameRange ParseFrameRange(const std::string& text) {
  const auto invalid = [&text](const std::string& why) {
    return InputError(StrCat("frame selection '", text, "': ", why,
                             " (expected N, BEGIN:END or BEGIN:END:STEP)"));
  };
  FrameRange range;
  const std::vector<std::string> parts = Split(text, ':');
  if (text.empty()) return range;
  if (parts.size() == 1) {
    const std::optional<size_t> count = ParseIndex(parts[0]);
    if (!count) throw invalid("not a frame count");
    if (*count > 0) range.end = *count;
    return range;
  }
  if (parts.size() > 3) throw invalid("too many fields");
  const std::optional<size_t> begin =
      parts[0].empty() ? std::optional<size_t>(0) : ParseIndex(parts[0]);
  if (!begin) throw invalid("BEGIN is not a frame index");
  range.begin = *begin;
  if (!parts[1].empty()) {
    const std::optional<size_t> end = ParseIndex(parts[1]);
    if (!end) throw invalid("END is not a frame index");
    if (*end <= range.begin) throw invalid("END must be after BEGIN");
    range.end = *end;
  }
  if (parts.size() == 3 && !parts[2].empty()) {
    const std::optional<size_t> step = ParseIndex(parts[2]);
    if (!step || *step < 1) throw invalid("STEP must be at least 1");
    range.step = *step;
  }
  return range;
}

std::vector<size_t> SelectedFrames(const FrameRange& range, size_t count) {
  std::vector<size_t> indices;
  for (size_t i = range.begin; i < count && i < range.end; i += range.step) indices.push_back(i);
  return indices;
}

Dataset SelectFrames(Dataset dataset, const FrameRange& range) {
  if (range.all()) return dataset;
  std::vector<FrameRecord> kept;
  for (size_t i : SelectedFrames(range, dataset.frames.size())) kept.push_back(dataset.frames[i]);
  if (kept.empty()) {
    throw InputError(StrCat(dataset.root, ": the frame selection holds none of its ",
                            dataset.frames.size(), " frames"));
  }
  dataset.frames = std::move(kept);
  return dataset;
}

}  // namespace visloc
