#include "dataset/dataset.h"

#include <algorithm>
#include <filesystem>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "dataset/euroc.h"
#include "dataset/kitti.h"

namespace visloc {

std::string ToString(DatasetFormat format) {
  return format == DatasetFormat::kEuroc ? "euroc" : "kitti";
}

DatasetFormat ParseDatasetFormat(const std::string& text) {
  const std::string lower = ToLower(text);
  if (lower == "euroc" || lower == "asl") return DatasetFormat::kEuroc;
  if (lower == "kitti") return DatasetFormat::kKitti;
  throw InputError(StrCat("unknown dataset format '", text, "' (expected euroc or kitti)"));
}

std::optional<DatasetFormat> ParseOptionalDatasetFormat(const std::string& text) {
  if (text.empty()) return std::nullopt;
  return ParseDatasetFormat(text);
}

Rigid3d Dataset::right_from_left() const {
  VISLOC_CHECK(right.has_value(), "dataset ", root, " has no right camera");
  return right->body_from_cam.Inverse() * left.body_from_cam;
}

Trajectory Dataset::GroundTruthLeftCam() const {
  Trajectory world_from_cam;
  constexpr int64_t kMaxGapNs = 50'000'000;
  for (const FrameRecord& frame : frames) {
    const auto world_from_body_at = InterpolateAt(world_from_body, frame.timestamp_ns, kMaxGapNs);
    if (world_from_body_at) {
      world_from_cam.push_back({frame.timestamp_ns, *world_from_body_at * left.body_from_cam});
    }
  }
  return world_from_cam;
}

cv::Mat LoadGreyImage(const std::string& path, int expected_width, int expected_height) {
  if (!std::filesystem::is_regular_file(path)) throw InputError(StrCat(path, ": no such image"));
  std::string why;
  cv::Mat image = image::ReadGrey(path, &why);
  if (image.empty()) throw InputError(why);  // "PATH: truncated PNG: ..."
  if (expected_width > 0 && (image.cols != expected_width || image.rows != expected_height)) {
    throw InputError(StrCat(path, ": image is ", image.cols, "x", image.rows,
                            " but the calibration says ", expected_width, "x", expected_height));
  }
  return image;
}

Dataset ReadDataset(const std::string& dir, std::optional<DatasetFormat> format) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(dir)) throw InputError(StrCat(dir, ": no such dataset directory"));
  if (!format) {
    if (fs::is_directory(fs::path(dir) / "mav0")) {
      format = DatasetFormat::kEuroc;
    } else if (fs::is_directory(fs::path(dir) / "image_0")) {
      format = DatasetFormat::kKitti;
    } else {
      throw InputError(StrCat(dir,
                              ": neither an EuRoC dataset (mav0/) nor a KITTI sequence "
                              "(image_0/)"));
    }
  }
  return *format == DatasetFormat::kEuroc ? ReadEuroc(dir) : ReadKitti(dir);
}

const std::pair<int64_t, std::string>* CameraStream::Nearest(int64_t timestamp_ns,
                                                             int64_t tolerance_ns) const {
  const auto after = std::lower_bound(
      images.begin(), images.end(), timestamp_ns,
      [](const std::pair<int64_t, std::string>& image, int64_t t) { return image.first < t; });
  const std::pair<int64_t, std::string>* best = nullptr;
  for (auto it : {after, after == images.begin() ? images.end() : std::prev(after)}) {
    if (it == images.end()) continue;
    const int64_t offset = std::abs(it->first - timestamp_ns);
    if (offset <= tolerance_ns &&
        (best == nullptr || offset < std::abs(best->first - timestamp_ns)))
      best = &*it;
  }
  return best;
}

}  // namespace visloc
