#include "dataset/euroc.h"

#include <cstdio>
#include <filesystem>

#include <yaml-cpp/yaml.h>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/strings.h"
#include "core/util/text_file.h"

namespace visloc {
namespace fs = std::filesystem;
namespace {

// Reads a YAML sequence of numbers of the expected length, or throws naming key and line.
std::vector<double> ReadNumbers(const std::string& path, const YAML::Node& parent,
                                const std::string& key, size_t expected) {
  const YAML::Node node = parent[key];
  if (!node) throw InputError(StrCat(path, ": missing '", key, "'"));
  const int line = node.Mark().line + 1;
  if (!node.IsSequence() || node.size() != expected) {
    ThrowAtLine(path, line, StrCat("'", key, "' must be a list of ", expected, " numbers"));
  }
  std::vector<double> values;
  for (const YAML::Node& item : node) {
    const auto value = ParseDouble(item.Scalar());
    if (!value)
      ThrowAtLine(path, line, StrCat("'", key, "' has a non-number '", item.Scalar(), "'"));
    values.push_back(*value);
  }
  return values;
}

std::string ReadString(const std::string& path, const YAML::Node& root, const std::string& key) {
  const YAML::Node node = root[key];
  if (!node || !node.IsScalar()) throw InputError(StrCat(path, ": missing '", key, "'"));
  return node.Scalar();
}

Rigid3d ReadTransform(const std::string& path, const YAML::Node& root) {
  const YAML::Node t_bs = root["T_BS"];
  if (!t_bs) throw InputError(StrCat(path, ": missing 'T_BS'"));
  const std::vector<double> data = ReadNumbers(path, t_bs, "data", 16);
  Eigen::Matrix<double, 3, 4> matrix;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) matrix(r, c) = data[r * 4 + c];
  }
  if ((matrix.leftCols<3>().transpose() * matrix.leftCols<3>() - Eigen::Matrix3d::Identity())
          .norm() > 1e-3) {
    ThrowAtLine(path, t_bs.Mark().line + 1, "T_BS rotation is not orthonormal");
  }
  return Rigid3d::FromMatrix(matrix);
}

YAML::Node LoadYaml(const std::string& path) {
  if (!fs::is_regular_file(path)) throw InputError(StrCat(path, ": no such file"));
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    ThrowAtLine(path, e.mark.line + 1, e.msg);
  }
}

}  // namespace

CameraInfo ReadSensorYaml(const std::string& path) {
  const YAML::Node root = LoadYaml(path);
  try {
    const std::string model = ReadString(path, root, "camera_model");
    if (model != "pinhole") {
      throw InputError(StrCat(path, ": unsupported camera_model '", model, "' (expected pinhole)"));
    }
    const std::vector<double> resolution = ReadNumbers(path, root, "resolution", 2);
    const std::vector<double> k = ReadNumbers(path, root, "intrinsics", 4);
    // Kalibr and EuRoC: radial-tangential (radtan) or equidistant (fisheye, Kannala-Brandt).
    Lens lens;
    if (root["distortion_model"]) {
      const std::string distortion_model = ReadString(path, root, "distortion_model");
      if (distortion_model != "none") {
        LensModel model;
        try {
          model = ParseLensModel(distortion_model);
        } catch (const InputError&) {
          ThrowAtLine(path, root["distortion_model"].Mark().line + 1,
                      StrCat("unsupported distortion_model '", distortion_model,
                             "' (expected radial-tangential, equidistant or none)"));
        }
        const std::vector<double> d = ReadNumbers(path, root, "distortion_coefficients", 4);
        lens = model == LensModel::kEquidistant ? Lens::Equidistant(d[0], d[1], d[2], d[3])
                                                : Lens(d[0], d[1], d[2], d[3]);
      }
    }
    if (resolution[0] < 1 || resolution[1] < 1 || k[0] <= 0 || k[1] <= 0) {
      throw InputError(StrCat(path, ": invalid resolution or focal length"));
    }
    CameraInfo info;
    info.camera = Camera(static_cast<int>(resolution[0]), static_cast<int>(resolution[1]),
                                k[0], k[1], k[2], k[3], lens);
    info.body_from_cam = ReadTransform(path, root);
    if (root["rate_hz"]) {
      const auto rate = ParseDouble(root["rate_hz"].Scalar());
      if (!rate || *rate <= 0) ThrowAtLine(path, root["rate_hz"].Mark().line + 1, "bad rate_hz");
      info.rate_hz = *rate;
    }
    return info;
  } catch (const YAML::Exception& e) {
    ThrowAtLine(path, e.mark.line + 1, e.msg);
  }
}

namespace {

void RequireIncreasing(const std::string& path, const DataRow& row, int64_t previous,
                       int64_t current, bool first) {
  if (!first && current <= previous) {
    ThrowAtLine(path, row.line,
                StrCat("timestamp ", current, " does not increase (previous ", previous, ")"));
  }
}

// Reads cam*/data.csv: "timestamp [ns],filename". Returns (timestamp, image path) pairs.
std::vector<std::pair<int64_t, std::string>> ReadCameraCsv(const std::string& cam_dir) {
  const std::string path = cam_dir + "/data.csv";
  if (!fs::is_regular_file(path)) throw InputError(StrCat(path, ": no such file"));
  std::vector<std::pair<int64_t, std::string>> images;
  for (const DataRow& row : ReadDataRows(path, ',')) {
    if (row.fields.size() != 2) {
      ThrowAtLine(path, row.line,
                  StrCat("expected 2 fields (timestamp,filename), found ", row.fields.size()));
    }
    const int64_t timestamp = FieldAsInt64(path, row, 0);
    RequireIncreasing(path, row, images.empty() ? 0 : images.back().first, timestamp,
                      images.empty());
    const std::string image = cam_dir + "/data/" + row.fields[1];
    if (!fs::is_regular_file(image)) ThrowAtLine(path, row.line, StrCat("missing image ", image));
    images.emplace_back(timestamp, image);
  }
  if (images.empty()) throw InputError(StrCat(path, ": no images listed"));
  return images;
}

std::vector<ImuSample> ReadImuCsv(const std::string& path) {
  std::vector<ImuSample> samples;
  for (const DataRow& row : ReadDataRows(path, ',')) {
    if (row.fields.size() != 7) {
      ThrowAtLine(path, row.line, StrCat("expected 7 fields, found ", row.fields.size()));
    }
    ImuSample sample;
    sample.timestamp_ns = FieldAsInt64(path, row, 0);
    RequireIncreasing(path, row, samples.empty() ? 0 : samples.back().timestamp_ns,
                      sample.timestamp_ns, samples.empty());
    for (int i = 0; i < 3; ++i) {
      sample.gyro_radps[i] = FieldAsDouble(path, row, 1 + i);
      sample.accel_mps2[i] = FieldAsDouble(path, row, 4 + i);
    }
    samples.push_back(sample);
  }
  return samples;
}

// Reads a pose CSV. `quaternion_first` selects EuRoC ground truth's column order
// (p, q_w, q_x, q_y, q_z) versus odometry0's (p, q_x, q_y, q_z, q_w).
Trajectory ReadPoseCsv(const std::string& path, bool quaternion_w_first) {
  Trajectory trajectory;
  for (const DataRow& row : ReadDataRows(path, ',')) {
    if (row.fields.size() < 8) {
      ThrowAtLine(path, row.line, StrCat("expected at least 8 fields, found ", row.fields.size()));
    }
    const int64_t timestamp = FieldAsInt64(path, row, 0);
    RequireIncreasing(path, row, trajectory.empty() ? 0 : trajectory.back().timestamp_ns, timestamp,
                      trajectory.empty());
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = FieldAsDouble(path, row, i + 1);
    const Eigen::Quaterniond q = quaternion_w_first ? Eigen::Quaterniond(v[3], v[4], v[5], v[6])
                                                    : Eigen::Quaterniond(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      ThrowAtLine(path, row.line, StrCat("quaternion is not unit (norm ", q.norm(), ")"));
    }
    trajectory.push_back({timestamp, Rigid3d(q, Eigen::Vector3d(v[0], v[1], v[2]))});
  }
  return trajectory;
}

// Cameras of a stereo rig are triggered together; a recording may still list an image one
// camera dropped, or stamp the two a little apart.
constexpr int64_t kMaxPairOffsetNs = 2'000'000;

// Pairs each left image with the right image nearest in time, both lists sorted by time; images
// without a partner within kMaxPairOffsetNs are counted and left out.
std::vector<FrameRecord> PairByTimestamp(
    const std::vector<std::pair<int64_t, std::string>>& left,
    const std::vector<std::pair<int64_t, std::string>>& right, StereoPairing* pairing) {
  std::vector<FrameRecord> frames;
  size_t j = 0;
  for (const auto& [timestamp, path] : left) {
    while (j < right.size() && right[j].first < timestamp - kMaxPairOffsetNs) {
      ++pairing->unpaired_right;
      ++j;
    }
    if (j < right.size() && std::abs(right[j].first - timestamp) <= kMaxPairOffsetNs) {
      pairing->max_offset_ns =
          std::max(pairing->max_offset_ns, std::abs(right[j].first - timestamp));
      frames.push_back({timestamp, path, right[j].second});
      ++j;
    } else {
      ++pairing->unpaired_left;
    }
  }
  pairing->unpaired_right += static_cast<int>(right.size() - j);
  return frames;
}

}  // namespace

Dataset ReadEuroc(const std::string& dir) {
  const std::string mav0 = dir + "/mav0";
  if (!fs::is_directory(mav0)) throw InputError(StrCat(dir, ": not an EuRoC dataset (no mav0/)"));
  if (!fs::is_directory(mav0 + "/cam0")) throw InputError(StrCat(mav0, "/cam0: no such folder"));
  Dataset dataset;
  dataset.root = dir;
  dataset.format = DatasetFormat::kEuroc;
  dataset.left = ReadSensorYaml(mav0 + "/cam0/sensor.yaml");
  const auto left_images = ReadCameraCsv(mav0 + "/cam0");
  std::vector<std::pair<int64_t, std::string>> right_images;
  if (fs::is_directory(mav0 + "/cam1")) {
    dataset.right = ReadSensorYaml(mav0 + "/cam1/sensor.yaml");
    right_images = ReadCameraCsv(mav0 + "/cam1");
    const Camera& l = dataset.left.camera;
    const Camera& r = dataset.right->camera;
    if (l.width() != r.width() || l.height() != r.height()) {
      throw InputError(StrCat(mav0, "/cam1/sensor.yaml: resolution differs from cam0"));
    }
  }
  if (!dataset.right) {
    for (const auto& [timestamp, path] : left_images) {
      dataset.frames.push_back({timestamp, path, ""});
    }
  } else {
    dataset.frames = PairByTimestamp(left_images, right_images, &dataset.pairing);
    if (dataset.frames.empty()) {
      throw InputError(StrCat(mav0, ": no cam0 image has a cam1 image within ",
                              kMaxPairOffsetNs / 1e6, " ms"));
    }
  }
  for (int c = 2; fs::is_directory(StrCat(mav0, "/cam", c)); ++c) {
    const std::string folder = StrCat(mav0, "/cam", c);
    dataset.other_cameras.push_back(
        {StrCat("cam", c), ReadSensorYaml(folder + "/sensor.yaml"), ReadCameraCsv(folder)});
  }
  if (fs::is_regular_file(mav0 + "/imu0/data.csv"))
    dataset.imu = ReadImuCsv(mav0 + "/imu0/data.csv");
  if (fs::is_regular_file(mav0 + "/odometry0/data.csv")) {
    dataset.odom_from_cam = ReadPoseCsv(mav0 + "/odometry0/data.csv", /*quaternion_w_first=*/false);
  }
  const std::string gt = mav0 + "/state_groundtruth_estimate0/data.csv";
  if (fs::is_regular_file(gt))
    dataset.world_from_body = ReadPoseCsv(gt, /*quaternion_w_first=*/true);
  return dataset;
}

namespace {

std::string FormatNumbers(const double* values, int count) {
  std::string out = "[";
  char buffer[40];
  for (int i = 0; i < count; ++i) {
    std::snprintf(buffer, sizeof(buffer), "%s%.17g", i ? ", " : "", values[i]);
    out += buffer;
  }
  return out + "]";
}

}  // namespace

void WriteSensorYaml(const std::string& path, const CameraInfo& info, const std::string& comment) {
  const Eigen::Matrix4d t_bs = info.body_from_cam.ToMatrix4();
  double data[16];
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) data[r * 4 + c] = t_bs(r, c);
  }
  const Camera& cam = info.camera;
  const double resolution[2] = {static_cast<double>(cam.width()),
                                static_cast<double>(cam.height())};
  const double intrinsics[4] = {cam.fx(), cam.fy(), cam.cx(), cam.cy()};
  const double* distortion = cam.lens().coefficients.data();
  std::string out =
      "# General sensor definitions.\nsensor_type: camera\ncomment: " + comment +
      "\n\n# Sensor extrinsics wrt. the body-frame.\nT_BS:\n  cols: 4\n  rows: 4\n"
      "  data: " +
      FormatNumbers(data, 16) + "\n\n# Camera specific definitions.\n" +
      (info.rate_hz > 0 ? "rate_hz: " + StrCat(info.rate_hz) + "\n" : std::string()) +
      "resolution: " + FormatNumbers(resolution, 2) +
      "\ncamera_model: pinhole\nintrinsics: " + FormatNumbers(intrinsics, 4) +
      " #fu, fv, cu, cv\n" + "distortion_model: " + LensModelName(cam.lens().model) +
      "\ndistortion_coefficients: " +
      FormatNumbers(distortion, 4) + "\n";
  WriteFileAtomically(path, out);
}

namespace {

void MakeDirectories(const std::string& path) {
  std::error_code error;
  fs::create_directories(path, error);
  if (error) throw InputError(StrCat(path, ": cannot create folder: ", error.message()));
}

}  // namespace

EurocWriter::EurocWriter(const std::string& dir, const CameraInfo& left,
                         const std::optional<CameraInfo>& right)
    : mav0_(dir + "/mav0"), left_(left), right_(right) {
  MakeDirectories(mav0_ + "/cam0/data");
  WriteSensorYaml(mav0_ + "/cam0/sensor.yaml", left_, "left camera (reference)");
  if (right_) {
    MakeDirectories(mav0_ + "/cam1/data");
    WriteSensorYaml(mav0_ + "/cam1/sensor.yaml", *right_, "right camera");
  }
}

void EurocWriter::AddCamera(const CameraInfo& info, const std::string& comment) {
  VISLOC_CHECK(timestamps_ns_.empty(), "cameras are added before the first frame");
  const std::string folder = StrCat(mav0_, "/cam", others_.size() + 2);
  MakeDirectories(folder + "/data");
  WriteSensorYaml(folder + "/sensor.yaml", info, comment);
  others_.push_back(info);
}

void EurocWriter::AddFrame(int64_t timestamp_ns, const cv::Mat& left, const cv::Mat& right,
                           const std::vector<cv::Mat>& others) {
  VISLOC_CHECK(others.size() == others_.size(), "a frame of ", others.size(),
               " further images for ", others_.size(), " further cameras");
  VISLOC_CHECK(timestamps_ns_.empty() || timestamp_ns > timestamps_ns_.back(),
               "frame timestamps must increase: ", timestamp_ns);
  const std::string name = StrCat(timestamp_ns, ".png");
  auto write = [&](const std::string& path, const cv::Mat& image, const CameraInfo& info) {
    VISLOC_CHECK(image.type() == CV_8UC1 && image.cols == info.camera.width() &&
                     image.rows == info.camera.height(),
                 "image must be 8-bit grey of the calibrated size");
    std::string why;
    if (!image::WritePng(path, image, 1, &why)) throw InputError(why);
  };
  write(mav0_ + "/cam0/data/" + name, left, left_);
  if (right_) write(mav0_ + "/cam1/data/" + name, right, *right_);
  for (size_t c = 0; c < others_.size(); ++c) {
    write(StrCat(mav0_, "/cam", c + 2, "/data/", name), others[c], others_[c]);
  }
  timestamps_ns_.push_back(timestamp_ns);
}

void EurocWriter::Finish(const std::vector<ImuSample>& imu, const Trajectory& odom_from_cam,
                         const Trajectory& world_from_body) {
  std::string images = "#timestamp [ns],filename\n";
  for (int64_t t : timestamps_ns_) images += StrCat(t, ",", t, ".png\n");
  WriteFileAtomically(mav0_ + "/cam0/data.csv", images);
  if (right_) WriteFileAtomically(mav0_ + "/cam1/data.csv", images);
  for (size_t c = 0; c < others_.size(); ++c) {
    WriteFileAtomically(StrCat(mav0_, "/cam", c + 2, "/data.csv"), images);
  }
  char buffer[512];
  if (!imu.empty()) {
    MakeDirectories(mav0_ + "/imu0");
    std::string out =
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
        "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
    for (const ImuSample& s : imu) {
      std::snprintf(buffer, sizeof(buffer), "%lld,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n",
                    static_cast<long long>(s.timestamp_ns), s.gyro_radps.x(), s.gyro_radps.y(),
                    s.gyro_radps.z(), s.accel_mps2.x(), s.accel_mps2.y(), s.accel_mps2.z());
      out += buffer;
    }
    WriteFileAtomically(mav0_ + "/imu0/data.csv", out);
    WriteFileAtomically(mav0_ + "/imu0/sensor.yaml",
                        "sensor_type: imu\ncomment: body frame IMU\nT_BS:\n  cols: 4\n  rows: 4\n"
                        "  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, "
                        "0.0, 0.0, 1.0]\nrate_hz: 200\n");
  }
  auto write_poses = [&](const std::string& folder, const Trajectory& poses, bool w_first,
                         const std::string& header) {
    if (poses.empty()) return;
    MakeDirectories(mav0_ + "/" + folder);
    std::string out = header;
    for (const StampedPose& p : poses) {
      const Eigen::Vector3d& t = p.pose.translation;
      const Eigen::Quaterniond& q = p.pose.rotation;
      if (w_first) {
        std::snprintf(buffer, sizeof(buffer), "%lld,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n",
                      static_cast<long long>(p.timestamp_ns), t.x(), t.y(), t.z(), q.w(), q.x(),
                      q.y(), q.z());
      } else {
        std::snprintf(buffer, sizeof(buffer), "%lld,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n",
                      static_cast<long long>(p.timestamp_ns), t.x(), t.y(), t.z(), q.x(), q.y(),
                      q.z(), q.w());
      }
      out += buffer;
    }
    WriteFileAtomically(mav0_ + "/" + folder + "/data.csv", out);
  };
  write_poses("odometry0", odom_from_cam, false,
              "#timestamp [ns],x [m],y [m],z [m],qx [],qy [],qz [],qw []\n");
  write_poses("state_groundtruth_estimate0", world_from_body, true,
              "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
              "q_RS_y [],q_RS_z []\n");
}

}  // namespace visloc
