#include "ros/bag/bag_import.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>

#include "core/util/check.h"
#include "dataset/euroc.h"

namespace visloc::bag {
namespace {

namespace fs = std::filesystem;

const std::set<std::string> kImageTypes = {"sensor_msgs/Image", "sensor_msgs/CompressedImage"};

// The bag's topics of the given kinds, for error messages: "/a (sensor_msgs/Image, 95)".
std::string ListTopics(const std::vector<ros_msg::TopicInfo>& topics, const std::set<std::string>& types) {
  std::string list;
  for (const ros_msg::TopicInfo& t : topics) {
    if (!types.count(ros_msg::NormalizeTypeName(t.type))) continue;
    list += StrCat(list.empty() ? "" : ", ", t.name, " (", t.type, ", ", t.messages, ")");
  }
  return list.empty() ? "none" : list;
}

// Checks that `topic` is in the bag with one of `types`; `flag` names the option for errors.
void RequireTopic(const std::vector<ros_msg::TopicInfo>& topics, const std::string& topic,
                  const std::set<std::string>& types, const std::string& flag,
                  const std::string& kind) {
  auto found = std::find_if(topics.begin(), topics.end(),
                            [&](const ros_msg::TopicInfo& t) { return t.name == topic; });
  if (found == topics.end()) {
    throw InputError(StrCat(flag, " ", topic, ": no such topic in the bag; its ", kind,
                            " topics: ", ListTopics(topics, types)));
  }
  if (!types.count(ros_msg::NormalizeTypeName(found->type))) {
    std::string wanted;
    for (const std::string& type : types) wanted += (wanted.empty() ? "" : " or ") + type;
    throw InputError(
        StrCat(flag, " ", topic, " is a ", found->type, " topic; ", flag, " takes ", wanted));
  }
  if (found->messages == 0) throw InputError(StrCat(flag, " ", topic, " has no messages"));
}

// The first CameraInfo message of each wanted topic.
std::map<std::string, ros_msg::CameraInfoMessage> FirstCameraInfos(BagReader& reader,
                                                          const std::vector<std::string>& topics) {
  std::map<std::string, ros_msg::CameraInfoMessage> first;
  reader.Read(topics, [&](const ros_msg::BagMessage& m) {
    if (const auto* info = std::get_if<ros_msg::CameraInfoMessage>(&m.message))
      first.emplace(m.topic, *info);
  });
  return first;
}

struct Cameras {
  CameraInfo left;
  std::optional<CameraInfo> right;
  std::string source;
};

Cameras CamerasFromInfo(BagReader& reader, const std::vector<ros_msg::TopicInfo>& topics,
                        const ImportOptions& options) {
  const bool stereo = !options.right_topic.empty();
  const std::string left_info = options.left_info_topic.empty()
                                    ? CameraInfoTopicFor(options.left_topic)
                                    : options.left_info_topic;
  const std::string right_info = !stereo ? ""
                                 : options.right_info_topic.empty()
                                     ? CameraInfoTopicFor(options.right_topic)
                                     : options.right_info_topic;
  const std::set<std::string> info_type = {"sensor_msgs/CameraInfo"};
  auto require_info = [&](const std::string& topic, const char* flag, const char* yaml_flag) {
    try {
      RequireTopic(topics, topic, info_type, flag, "camera_info");
    } catch (const InputError& e) {
      throw InputError(StrCat(e.what(), ". Without camera_info, give ", yaml_flag,
                              " sensor.yaml (EuRoC format)"));
    }
  };
  require_info(left_info, "--left-info", "--left-yaml");
  if (stereo) require_info(right_info, "--right-info", "--right-yaml");
  std::vector<std::string> wanted = {left_info};
  if (stereo) wanted.push_back(right_info);
  const auto infos = FirstCameraInfos(reader, wanted);
  Cameras cameras;
  cameras.source = "camera_info";
  const ros_msg::CameraInfoMessage& l = infos.at(left_info);
  cameras.left.camera = ros_msg::CameraFromInfo(l, left_info, options.max_dropped_distortion_px);
  cameras.left.body_from_cam = Rigid3d::Identity();  // The left camera is the body frame.
  if (stereo) {
    const ros_msg::CameraInfoMessage& r = infos.at(right_info);
    CameraInfo right;
    right.camera = ros_msg::CameraFromInfo(r, right_info, options.max_dropped_distortion_px);
    right.body_from_cam = ros_msg::LeftFromRight(l, r);
    cameras.right = right;
  }
  return cameras;
}

// The image in a message of an image topic; InputError when its size is not the camera's.
const cv::Mat& CheckedImage(const ros_msg::BagMessage& m, const CameraInfo& camera) {
  const auto* image = std::get_if<ros_msg::ImageMessage>(&m.message);
  VISLOC_CHECK(image != nullptr, "image topic without an image");
  if (image->grey.cols != camera.camera.width() || image->grey.rows != camera.camera.height()) {
    throw InputError(StrCat(m.topic, " image stamped ", ros_msg::StampText(image->header.stamp_ns), " s is ",
                            image->grey.cols, "x", image->grey.rows, "; its camera is ",
                            camera.camera.width(), "x", camera.camera.height()));
  }
  return image->grey;
}

double MedianRateHz(const std::vector<int64_t>& stamps_ns) {
  if (stamps_ns.size() < 2) return 0.0;
  std::vector<int64_t> periods;
  for (size_t i = 1; i < stamps_ns.size(); ++i) periods.push_back(stamps_ns[i] - stamps_ns[i - 1]);
  std::nth_element(periods.begin(), periods.begin() + periods.size() / 2, periods.end());
  return 1e9 / static_cast<double>(periods[periods.size() / 2]);
}

}  // namespace

std::string CameraInfoTopicFor(const std::string& image_topic) {
  std::string topic = image_topic;
  const std::string compressed = "/compressed";
  if (topic.size() > compressed.size() &&
      topic.compare(topic.size() - compressed.size(), compressed.size(), compressed) == 0) {
    topic.resize(topic.size() - compressed.size());
  }
  const size_t slash = topic.rfind('/');
  return (slash == std::string::npos ? "" : topic.substr(0, slash + 1)) + "camera_info";
}

void ImportOptions::Check() const {
  if (left_topic.empty()) throw CheckError("the left image topic (--left) is required");
  if (left_topic == right_topic)
    throw CheckError(StrCat("--left and --right name the same topic ", left_topic));
  if (!(pair_tolerance_ns >= 0 && pair_tolerance_ns <= 1'000'000'000)) {
    throw CheckError(StrCat("the pairing tolerance must be 0 to 1000 ms, not ",
                            pair_tolerance_ns * 1e-6, " ms"));
  }
  if (right_yaml && !left_yaml) throw CheckError("--right-yaml needs --left-yaml");
  if (!right_topic.empty() && left_yaml.has_value() != right_yaml.has_value()) {
    throw CheckError("--left-yaml and --right-yaml go together for a stereo import");
  }
  if (!imu_topic.empty() && !left_yaml) {
    throw CheckError(
        "--imu needs --left-yaml/--right-yaml: camera_info carries no camera-to-IMU transform, "
        "and IMU samples must be given in the body frame of the cameras' T_BS");
  }
}

ImportStats ImportBag(BagReader& reader, const ImportOptions& options, const std::string& out_dir,
                      const ImportProgressFn& progress) {
  options.Check();
  std::error_code error;
  if (fs::exists(out_dir, error) && !fs::is_empty(out_dir, error)) {
    throw InputError(StrCat(out_dir, ": exists and is not empty; import into a new folder"));
  }
  const std::vector<ros_msg::TopicInfo> topics = reader.Topics();
  const bool stereo = !options.right_topic.empty();
  RequireTopic(topics, options.left_topic, kImageTypes, "--left", "image");
  if (stereo) RequireTopic(topics, options.right_topic, kImageTypes, "--right", "image");
  if (!options.imu_topic.empty()) {
    RequireTopic(topics, options.imu_topic, {"sensor_msgs/Imu"}, "--imu", "sensor_msgs/Imu");
  }
  if (!options.odometry_topic.empty()) {
    RequireTopic(topics, options.odometry_topic, {"nav_msgs/Odometry"}, "--odometry",
                 "nav_msgs/Odometry");
  }

  Cameras cameras;
  if (options.left_yaml) {
    cameras = {*options.left_yaml, stereo ? options.right_yaml : std::nullopt, "sensor.yaml"};
  } else {
    cameras = CamerasFromInfo(reader, topics, options);
  }

  const std::string partial = out_dir + ".partial";
  fs::remove_all(partial, error);
  ImportStats stats;
  stats.camera_source = cameras.source;
  stats.left = cameras.left;
  stats.right = cameras.right;
  std::vector<ImuSample> imu;
  Trajectory odom_from_cam;
  int64_t first_ns = INT64_MAX, last_ns = INT64_MIN;
  std::vector<int64_t> frame_stamps_ns;
  try {
    EurocWriter writer(partial, cameras.left, cameras.right);
    auto write = [&](int64_t stamp_ns, const cv::Mat& left, const cv::Mat& right) {
      writer.AddFrame(stamp_ns, left, right);
      frame_stamps_ns.push_back(stamp_ns);
      first_ns = std::min(first_ns, stamp_ns);
      last_ns = std::max(last_ns, stamp_ns);
      ++stats.frames;
      if (progress) progress(stats.frames);
    };
    StereoPairer pairer(options.pair_tolerance_ns, write);
    int64_t last_mono_ns = INT64_MIN;
    std::vector<std::string> wanted = {options.left_topic};
    for (const std::string* t :
         {&options.right_topic, &options.imu_topic, &options.odometry_topic}) {
      if (!t->empty()) wanted.push_back(*t);
    }
    reader.Read(wanted, [&](const ros_msg::BagMessage& m) {
      if (m.topic == options.left_topic) {
        ++stats.left_images;
        const cv::Mat& grey = CheckedImage(m, cameras.left);
        const int64_t stamp = std::get<ros_msg::ImageMessage>(m.message).header.stamp_ns;
        if (stereo) {
          pairer.AddLeft(stamp, grey);
        } else if (stamp > last_mono_ns) {
          write(stamp, grey, cv::Mat());
          last_mono_ns = stamp;
        } else {
          ++stats.pairing.out_of_order;
        }
      } else if (m.topic == options.right_topic) {
        ++stats.right_images;
        pairer.AddRight(std::get<ros_msg::ImageMessage>(m.message).header.stamp_ns,
                        CheckedImage(m, *cameras.right));
      } else if (const auto* sample = std::get_if<ros_msg::ImuMessage>(&m.message)) {
        imu.push_back({sample->header.stamp_ns, sample->gyro_radps, sample->accel_mps2});
      } else if (const auto* odom = std::get_if<ros_msg::OdometryMessage>(&m.message)) {
        odom_from_cam.push_back(
            {odom->header.stamp_ns, odom->odom_from_child * options.base_from_cam});
      }
    });
    if (stereo) {
      pairer.Finish();
      const int out_of_order = stats.pairing.out_of_order;
      stats.pairing = pairer.stats();
      stats.pairing.out_of_order += out_of_order;
    }
    if (stats.frames == 0) {
      throw InputError(StrCat("no frame to write: ", stats.left_images, " left and ",
                              stats.right_images, " right images, none paired within ",
                              options.pair_tolerance_ns * 1e-6, " ms (--pair-tolerance-ms)"));
    }
    // Streams sorted by stamp (recording order may differ), duplicates dropped.
    auto by_time = [](const auto& a, const auto& b) { return a.timestamp_ns < b.timestamp_ns; };
    auto same_time = [](const auto& a, const auto& b) { return a.timestamp_ns == b.timestamp_ns; };
    std::stable_sort(imu.begin(), imu.end(), by_time);
    imu.erase(std::unique(imu.begin(), imu.end(), same_time), imu.end());
    std::stable_sort(odom_from_cam.begin(), odom_from_cam.end(), by_time);
    odom_from_cam.erase(std::unique(odom_from_cam.begin(), odom_from_cam.end(), same_time),
                        odom_from_cam.end());
    stats.imu_samples = static_cast<int>(imu.size());
    stats.odometry_poses = static_cast<int>(odom_from_cam.size());
    stats.duration_s = NsToSeconds(last_ns - first_ns);
    writer.Finish(imu, odom_from_cam, {});
    // The camera rate is known only now (the median frame period, which dropped frames do not
    // change): sensor.yaml is rewritten with it.
    const double rate_hz = MedianRateHz(frame_stamps_ns);
    stats.left.rate_hz = rate_hz;
    WriteSensorYaml(partial + "/mav0/cam0/sensor.yaml", stats.left, "left camera (reference)");
    if (stats.right) {
      stats.right->rate_hz = rate_hz;
      WriteSensorYaml(partial + "/mav0/cam1/sensor.yaml", *stats.right, "right camera");
    }
    ReadDataset(partial, DatasetFormat::kEuroc);  // What we wrote must read back.
  } catch (...) {
    fs::remove_all(partial, error);
    throw;
  }
  fs::remove(out_dir, error);  // An empty folder the user made is replaced.
  fs::rename(partial, out_dir, error);
  if (error) {
    throw InputError(
        StrCat(out_dir, ": cannot move the imported sequence into place: ", error.message()));
  }
  return stats;
}

}  // namespace visloc::bag
