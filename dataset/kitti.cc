#include "dataset/kitti.h"

#include <cstdio>
#include <filesystem>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"
#include "dataset/tum.h"

namespace visloc {
namespace fs = std::filesystem;
namespace {

std::string ImageName(int index) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%06d.png", index);
  return buffer;
}

// Reads "Pk: 12 numbers" rows of calib.txt into 3x4 matrices keyed by k.
std::vector<std::optional<Eigen::Matrix<double, 3, 4>>> ReadProjections(const std::string& path) {
  std::vector<std::optional<Eigen::Matrix<double, 3, 4>>> projections(4);
  for (const DataRow& row : ReadDataRows(path, ' ')) {
    const std::string& key = row.fields[0];
    if (key.size() != 3 || key[0] != 'P' || key[2] != ':' || key[1] < '0' || key[1] > '3') continue;
    if (row.fields.size() != 13) {
      ThrowAtLine(path, row.line, StrCat(key, " needs 12 numbers, found ", row.fields.size() - 1));
    }
    Eigen::Matrix<double, 3, 4> p;
    for (int i = 0; i < 12; ++i) p(i / 4, i % 4) = FieldAsDouble(path, row, i + 1);
    projections[key[1] - '0'] = p;
  }
  return projections;
}

std::string FindPosesFile(const fs::path& dir) {
  if (fs::is_regular_file(dir / "poses.txt")) return (dir / "poses.txt").string();
  const fs::path canonical = fs::weakly_canonical(dir);
  const fs::path shared =
      canonical.parent_path().parent_path() / "poses" / (canonical.filename().string() + ".txt");
  return fs::is_regular_file(shared) ? shared.string() : "";
}

}  // namespace

Dataset ReadKitti(const std::string& dir) {
  const fs::path root(dir);
  const std::string calib_path = (root / "calib.txt").string();
  const std::string times_path = (root / "times.txt").string();
  if (!fs::is_directory(root / "image_0"))
    throw InputError(StrCat(dir, "/image_0: no such folder"));
  if (!fs::is_regular_file(calib_path)) throw InputError(StrCat(calib_path, ": no such file"));
  if (!fs::is_regular_file(times_path)) throw InputError(StrCat(times_path, ": no such file"));

  const auto projections = ReadProjections(calib_path);
  if (!projections[0]) throw InputError(StrCat(calib_path, ": missing P0"));
  const Eigen::Matrix<double, 3, 4>& p0 = *projections[0];

  std::vector<int64_t> timestamps;
  for (const DataRow& row : ReadDataRows(times_path, ' ')) {
    const auto t = ParseSecondsToNs(row.fields[0]);
    if (!t) ThrowAtLine(times_path, row.line, "bad timestamp '" + row.fields[0] + "'");
    if (!timestamps.empty() && *t <= timestamps.back()) {
      ThrowAtLine(times_path, row.line, "timestamps must increase");
    }
    timestamps.push_back(*t);
  }
  if (timestamps.empty()) throw InputError(StrCat(times_path, ": no timestamps"));

  const bool stereo = fs::is_directory(root / "image_1");
  auto count_images = [](const fs::path& folder) {
    size_t count = 0;
    for (const auto& entry : fs::directory_iterator(folder)) {
      const std::string ext = ToLower(entry.path().extension().string());
      if (entry.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg")) ++count;
    }
    return count;
  };
  const size_t left_count = count_images(root / "image_0");
  if (left_count != timestamps.size()) {
    throw InputError(StrCat(dir, "/image_0: ", left_count, " images but times.txt has ",
                            timestamps.size(), " timestamps"));
  }
  if (stereo && count_images(root / "image_1") != left_count) {
    throw InputError(StrCat(dir, "/image_1: ", count_images(root / "image_1"),
                            " images but image_0 has ", left_count));
  }

  Dataset dataset;
  dataset.root = dir;
  dataset.format = DatasetFormat::kKitti;
  for (size_t i = 0; i < timestamps.size(); ++i) {
    const std::string name = ImageName(static_cast<int>(i));
    FrameRecord frame{timestamps[i], (root / "image_0" / name).string(), ""};
    if (!fs::is_regular_file(frame.left_path))
      throw InputError(StrCat(frame.left_path, ": missing image"));
    if (stereo) frame.right_path = (root / "image_1" / name).string();
    dataset.frames.push_back(std::move(frame));
  }
  // KITTI has no resolution in calib.txt: take it from the first image.
  std::string why;
  const cv::Mat first = image::ReadGrey(dataset.frames[0].left_path, &why);
  if (first.empty()) throw InputError(why);
  dataset.left.camera =
      Camera(first.cols, first.rows, p0(0, 0), p0(1, 1), p0(0, 2), p0(1, 2));
  if (timestamps.size() > 1) {
    dataset.left.rate_hz = (timestamps.size() - 1) / NsToSeconds(timestamps.back() - timestamps[0]);
  }
  if (stereo) {
    if (!projections[1]) throw InputError(StrCat(calib_path, ": missing P1 for image_1"));
    const double baseline_m = -(*projections[1])(0, 3) / (*projections[1])(0, 0);
    if (!(baseline_m > 0)) throw InputError(StrCat(calib_path, ": P1 gives baseline ", baseline_m));
    dataset.right = dataset.left;
    dataset.right->body_from_cam.translation = Eigen::Vector3d(baseline_m, 0, 0);
  }

  const std::string poses_path = FindPosesFile(root);
  if (!poses_path.empty()) {
    const auto rows = ReadDataRows(poses_path, ' ');
    if (rows.size() != timestamps.size()) {
      throw InputError(
          StrCat(poses_path, ": ", rows.size(), " poses but ", timestamps.size(), " frames"));
    }
    for (size_t i = 0; i < rows.size(); ++i) {
      if (rows[i].fields.size() != 12) {
        ThrowAtLine(poses_path, rows[i].line,
                    StrCat("expected 12 numbers, found ", rows[i].fields.size()));
      }
      Eigen::Matrix<double, 3, 4> m;
      for (int k = 0; k < 12; ++k) m(k / 4, k % 4) = FieldAsDouble(poses_path, rows[i], k);
      dataset.world_from_body.push_back({timestamps[i], Rigid3d::FromMatrix(m)});
    }
  }
  return dataset;
}

void WriteKittiCalibration(const std::string& dir, const Camera& camera, double baseline_m) {
  fs::create_directories(fs::path(dir) / "image_0");
  fs::create_directories(fs::path(dir) / "image_1");
  std::string out;
  char buffer[256];
  for (int k = 0; k < 4; ++k) {
    const double tx = k == 1 ? -camera.fx() * baseline_m : 0.0;
    std::snprintf(buffer, sizeof(buffer), "P%d: %.12e 0 %.12e %.12e 0 %.12e %.12e 0 0 0 1 0\n", k,
                  camera.fx(), camera.cx(), tx, camera.fy(), camera.cy());
    out += buffer;
  }
  WriteFileAtomically(dir + "/calib.txt", out);
}

void WriteKittiFrame(const std::string& dir, int index, const cv::Mat& left, const cv::Mat& right) {
  const std::string name = ImageName(index);
  for (const auto& [folder, image] : {std::pair{"image_0", left}, std::pair{"image_1", right}}) {
    const std::string path = dir + "/" + folder + "/" + name;
    std::string why;
    if (!image::WritePng(path, image, 1, &why)) throw InputError(why);
  }
}

void WriteKittiTimesAndPoses(const std::string& dir, const std::vector<int64_t>& timestamps_ns,
                             const Trajectory& left_cam_poses) {
  std::string times;
  for (int64_t t : timestamps_ns) times += FormatNsAsSeconds(t) + "\n";
  WriteFileAtomically(dir + "/times.txt", times);
  if (left_cam_poses.empty()) return;
  std::string poses;
  char buffer[64];
  for (const StampedPose& p : left_cam_poses) {
    const Eigen::Matrix<double, 3, 4> m = p.pose.ToMatrix3x4();
    for (int k = 0; k < 12; ++k) {
      std::snprintf(buffer, sizeof(buffer), k ? " %.12e" : "%.12e", m(k / 4, k % 4));
      poses += buffer;
    }
    poses += "\n";
  }
  WriteFileAtomically(dir + "/poses.txt", poses);
}

}  // namespace visloc
