// visloc_ros_node: a ROS 1 camera in, visloc poses out. The node is a client of visloc-server
// through the client library (visloc::client), so it inherits the robot link's behaviour:
// bounded frames in flight, drops when the link is slow, reconnection with the last pose as
// a hint.
//
// Subscribes (remap them):   image (sensor_msgs/Image through image_transport, or
//                            image/compressed with ~transport:=compressed), camera_info,
//                            odom (nav_msgs/Odometry, ~use_odometry), imu (sensor_msgs/Imu,
//                            ~use_imu)
// Publishes:                 ~pose (geometry_msgs/PoseWithCovarianceStamped, ~map_frame),
//                            ~status (std_msgs/String), /diagnostics, TF map -> odom (REP 105)
//                            with odometry, else map -> camera
// Service:                   ~relocalize (std_srvs/Trigger): the last image through the
//                            Relocalize RPC; a fix becomes the session's next hint.
// With ~mode:=map the node streams a stereo camera to the server's mapper instead
// (mapping_node.h, launch/visloc_mapping.launch).
// Frames: the image's frame_id is the camera's optical frame (x right, y down, z forward, as
// visloc's camera frame). Poses are map_from_cam, ~map_frame being the map's site frame (z up,
// REP 105: the frame map align tied it to, else its level frame) while ~site_frame is true (the
// default) and the map knows up; else the map's own frame (its first camera's). The hint sent
// back to the server stays in the map's own frame. No pose is published while lost.

#include <algorithm>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <image_transport/image_transport.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "proto/geometry_convert.h"
#include "ros/messages/ros_messages.h"
#include "ros/node/mapping_node.h"
#include "ros/node/pose_output.h"
#include "ros/node/ros_camera_info.h"
#include "ros/node/sensor_sync.h"
#include "visloc/client/session.h"

namespace visloc::ros_node {
namespace {

namespace vc = visloc::client;
using proto::FromProto;
using proto::ToProto;

std::string ReadFileOrEmpty(const std::string& path) {
  if (path.empty()) return "";
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// geometry_msgs' Quaternion and Point / Vector3 fields, whichever message holds them.
template <typename RosQuaternion, typename RosVector>
Rigid3d FromRos(const RosQuaternion& q, const RosVector& v) {
  return Rigid3d(Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized(),
                 Eigen::Vector3d(v.x, v.y, v.z));
}
template <typename RosQuaternion, typename RosVector>
void ToRos(const Rigid3d& pose, RosQuaternion* q, RosVector* v) {
  q->w = pose.rotation.w();
  q->x = pose.rotation.x();
  q->y = pose.rotation.y();
  q->z = pose.rotation.z();
  v->x = pose.translation.x();
  v->y = pose.translation.y();
  v->z = pose.translation.z();
}
Rigid3d FromRos(const geometry_msgs::Pose& p) { return FromRos(p.orientation, p.position); }
Rigid3d FromRos(const geometry_msgs::Transform& t) { return FromRos(t.rotation, t.translation); }
void ToRos(const Rigid3d& pose, geometry_msgs::Pose* p) {
  ToRos(pose, &p->orientation, &p->position);
}
void ToRos(const Rigid3d& pose, geometry_msgs::Transform* t) {
  ToRos(pose, &t->rotation, &t->translation);
}

double WallNowS() { return ros::WallTime::now().toSec(); }

ros::Time StampOf(int64_t ns) {
  ros::Time t;
  t.fromNSec(static_cast<uint64_t>(ns));
  return t;
}

class LocalizationNode {
 public:
  LocalizationNode(ros::NodeHandle& nh, ros::NodeHandle& pnh)
      : nh_(nh), pnh_(pnh), transport_(nh), tf_listener_(tf_buffer_) {
    ReadParameters();
    pose_pub_ = pnh_.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
    status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, /*latch=*/true);
    diagnostics_pub_ = nh_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    info_sub_ = nh_.subscribe("camera_info", 1, &LocalizationNode::OnCameraInfo, this);
    compressed_ = pnh_.param<std::string>("transport", "raw") == "compressed";
    if (compressed_) {
      // Debian ships no compressed image_transport plugin: the CompressedImage topic is read
      // directly, and its JPEG/PNG bytes go to the server as they are (no re-encoding).
      compressed_sub_ = nh_.subscribe(nh_.resolveName("image") + "/compressed", 2,
                                      &LocalizationNode::OnCompressedImage, this);
    } else {
      image_sub_ = transport_.subscribe("image", 2, &LocalizationNode::OnImage, this);
    }
    if (use_odometry_) odom_sub_ = nh_.subscribe("odom", 50, &LocalizationNode::OnOdometry, this);
    if (use_imu_) imu_sub_ = nh_.subscribe("imu", 400, &LocalizationNode::OnImu, this);
    SubscribeRigCameras();
    sync_.emplace(SyncOptions());
    if (use_odometry_ || use_imu_ || !rig_.empty()) {
      // Images held for their odometry or IMU go when the wait runs out, even with no message.
      sync_timer_ = nh_.createWallTimer(ros::WallDuration(0.02),
                                        [this](const ros::WallTimerEvent&) { SendReady(); });
    }
    relocalize_srv_ = pnh_.advertiseService("relocalize", &LocalizationNode::OnRelocalize, this);
    diagnostics_timer_ = nh_.createWallTimer(
        ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { PublishDiagnostics(); });
    PublishStatus("waiting for camera_info");
  }

  ~LocalizationNode() {
    std::unique_ptr<vc::Session> session;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      session = std::move(session_);
    }
    if (session) session->Close(std::chrono::milliseconds(500));
  }

 private:
  void ReadParameters() {
    options_.server = pnh_.param<std::string>("server", "127.0.0.1:50051");
    options_.map_name = pnh_.param<std::string>("map", "");
    if (options_.map_name.empty())
      throw std::runtime_error("parameter ~map (the map's name) is required");
    options_.robot_id = pnh_.param<std::string>("robot_id", ros::this_node::getName());
    options_.credentials.token = pnh_.param<std::string>("token", "");
    options_.credentials.tls_ca_pem = ReadFileOrEmpty(pnh_.param<std::string>("tls_ca", ""));
    const std::string encoding = pnh_.param<std::string>("encoding", "jpeg");
    options_.encoding = encoding == "png"   ? vc::Encoding::kPng
                        : encoding == "raw" ? vc::Encoding::kRaw
                                            : vc::Encoding::kJpeg;
    options_.jpeg_quality = pnh_.param("jpeg_quality", 90);
    options_.max_in_flight = pnh_.param("max_in_flight", 2);
    options_.frame_deadline = std::chrono::milliseconds(pnh_.param("frame_deadline_ms", 1000));
    double camera_height_m = 0.0;
    if (pnh_.getParam("camera_height_m", camera_height_m)) {
      options_.session.set_camera_height_m(camera_height_m);
    }
    map_frame_ = pnh_.param<std::string>("map_frame", "map");
    // REP 105's map has z up: the map's site frame, when the server knows it (pose_output.h).
    site_frame_ = pnh_.param("site_frame", true);
    camera_frame_override_ = pnh_.param<std::string>("camera_frame", "");
    publish_tf_ = pnh_.param("publish_tf", true);
    use_odometry_ = pnh_.param("use_odometry", false);
    use_imu_ = pnh_.param("use_imu", false);
    sensor_wait_s_ = pnh_.param("sensor_wait_s", 0.1);
    // A rig: the further cameras' namespaces, each with image_raw and camera_info ("/cam2,/cam3").
    std::stringstream rig_cameras(pnh_.param<std::string>("rig_cameras", ""));
    for (std::string name; std::getline(rig_cameras, name, ',');) {
      if (name.empty()) continue;
      rig_.push_back(std::make_unique<RigCameraTopics>());
      rig_.back()->ns = name;
    }
  }

  SensorSyncOptions SyncOptions() const {
    SensorSyncOptions sync;
    sync.odometry = use_odometry_;
    sync.imu = use_imu_;
    sync.cameras = rig_.size();
    sync.max_wait_s = sensor_wait_s_;
    return sync;
  }

  // The first camera_info opens the session (the server needs the camera model), and the
  // image that came just before it (drivers publish the image first) is sent on it.
  void OnCameraInfo(const sensor_msgs::CameraInfo& msg) {
    std::optional<vc::Frame> early;
    vc::Session* session = OpenSession(msg, &early);
    if (session && early) Receive(early->timestamp_ns, std::move(*early));
  }

  vc::Session* OpenSession(const sensor_msgs::CameraInfo& msg, std::optional<vc::Frame>* early) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (session_ || failed_) return nullptr;
    const ros_msg::CameraInfoMessage info = CameraInfoFromRos(msg);
    try {
      ToProto(ros_msg::CameraFromInfo(info, nh_.resolveName("camera_info")), &options_.camera);
    } catch (const std::exception& e) {
      failed_ = true;
      ROS_ERROR("visloc: %s", e.what());
      PublishStatus(std::string("error: ") + e.what());
      return nullptr;
    }
    camera_frame_ = camera_frame_override_.empty() ? msg.header.frame_id : camera_frame_override_;
    if (!rig_.empty() && !SetRigCameras(msg.header.frame_id)) return nullptr;
    // The camera's pose on the IMU is fixed when the session opens: with IMU, the session waits
    // (up to 1 s of camera_info) for the first IMU message and the TF between the two frames.
    if (use_imu_ && !SetBodyFromCamera(msg.header.frame_id)) {
      const double now_s = ros::WallTime::now().toSec();
      if (first_camera_info_s_ == 0.0) first_camera_info_s_ = now_s;
      if (now_s - first_camera_info_s_ < 1.0) return nullptr;
      ROS_WARN("visloc: no IMU message with a TF to %s within 1 s: IMU samples are not used",
               msg.header.frame_id.c_str());
      use_imu_ = false;
      sync_.emplace(SyncOptions());  // Nothing is waiting yet: no session before this.
    }
    options_.on_event = [this](const vc::Event& event) { OnEvent(event); };
    session_ = vc::Session::Open(options_);
    ROS_INFO("visloc: session on map '%s' at %s, camera %ux%u fx %.1f", options_.map_name.c_str(),
             options_.server.c_str(), msg.width, msg.height, msg.K[0]);
    PublishStatus("connecting");
    if (before_session_ &&
        before_session_->timestamp_ns == static_cast<int64_t>(msg.header.stamp.toNSec())) {
      --images_received_;  // Counted again when submitted.
      *early = std::move(before_session_);
    }
    before_session_.reset();
    return session_.get();
  }

  // Gyro samples are in the IMU's frame; the engine needs the camera's pose on it (from TF).
  // False while the IMU's frame or the transform is not known yet.
  bool SetBodyFromCamera(const std::string& camera_frame) {
    if (imu_frame_.empty()) return false;
    try {
      const auto t = tf_buffer_.lookupTransform(imu_frame_, camera_frame, ros::Time(0));
      ToProto(FromRos(t.transform), options_.session.mutable_body_from_cam());
      return true;
    } catch (const tf2::TransformException&) {
      return false;
    }
  }

  void OnOdometry(const nav_msgs::Odometry& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      odom_frame_ = msg.header.frame_id;
      odom_child_frame_ = msg.child_frame_id;
      const auto stamp_ns = static_cast<int64_t>(msg.header.stamp.toNSec());
      odometry_.Add(stamp_ns, FromRos(msg.pose.pose));
      sync_->gate().OnOdometry(stamp_ns, WallNowS());
      // Answers that came back before the odometry of their stamp get their map -> odom now.
      while (!waiting_for_odometry_.empty() &&
             odometry_.At(waiting_for_odometry_.front().timestamp_ns)) {
        PublishTransform(waiting_for_odometry_.front().timestamp_ns,
                         waiting_for_odometry_.front().pose);
        waiting_for_odometry_.pop_front();
      }
    }
    SendReady();
  }

  void OnImu(const sensor_msgs::Imu& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      imu_frame_ = msg.header.frame_id;
      v1::ImuSample sample;
      sample.set_timestamp_ns(static_cast<int64_t>(msg.header.stamp.toNSec()));
      sample.set_gyro_x(msg.angular_velocity.x);
      sample.set_gyro_y(msg.angular_velocity.y);
      sample.set_gyro_z(msg.angular_velocity.z);
      sample.set_accel_x(msg.linear_acceleration.x);
      sample.set_accel_y(msg.linear_acceleration.y);
      sample.set_accel_z(msg.linear_acceleration.z);
      if (imu_.size() < 2000) imu_.push_back(sample);
      sync_->gate().OnImu(sample.timestamp_ns(), WallNowS());
    }
    SendReady();
  }

  void OnImage(const sensor_msgs::ImageConstPtr& msg) {
    vc::Frame frame;
    try {
      frame.image = ros_msg::DecodeRawImage(
          msg->width, msg->height, msg->encoding, msg->is_bigendian != 0, msg->step,
          std::string_view(reinterpret_cast<const char*>(msg->data.data()), msg->data.size()));
    } catch (const std::exception& e) {
      ROS_ERROR_THROTTLE(5.0, "visloc: image refused: %s", e.what());
      return;
    }
    Receive(static_cast<int64_t>(msg->header.stamp.toNSec()), std::move(frame));
  }

  void OnCompressedImage(const sensor_msgs::CompressedImageConstPtr& msg) {
    vc::Frame frame;
    frame.encoded.assign(msg->data.begin(), msg->data.end());
    Receive(static_cast<int64_t>(msg->header.stamp.toNSec()), std::move(frame));
  }

  // A rig's further cameras: each one's image_raw (or, with ~transport:=compressed, its
  // image_raw/compressed) and camera_info in its namespace.
  void SubscribeRigCameras() {
    for (size_t c = 0; c < rig_.size(); ++c) {
      RigCameraTopics& camera = *rig_[c];
      camera.info_sub = nh_.subscribe<sensor_msgs::CameraInfo>(
          camera.ns + "/camera_info", 1, [this, c](const sensor_msgs::CameraInfoConstPtr& msg) {
            std::lock_guard<std::mutex> lock(mutex_);
            rig_[c]->info = *msg;
          });
      if (compressed_) {
        camera.compressed_sub = nh_.subscribe<sensor_msgs::CompressedImage>(
            camera.ns + "/image_raw/compressed", 2,
            [this, c](const sensor_msgs::CompressedImageConstPtr& msg) {
              OnRigImage(c, static_cast<int64_t>(msg->header.stamp.toNSec()), [&] {
                return ros_msg::DecodeCompressedImage(
                    msg->format, std::string_view(reinterpret_cast<const char*>(msg->data.data()),
                                                  msg->data.size()));
              });
            });
        continue;
      }
      camera.image_sub = transport_.subscribe(
          camera.ns + "/image_raw", 2,
          boost::function<void(const sensor_msgs::ImageConstPtr&)>(
              [this, c](const sensor_msgs::ImageConstPtr& msg) {
                OnRigImage(c, static_cast<int64_t>(msg->header.stamp.toNSec()), [&] {
                  return ros_msg::DecodeRawImage(
                      msg->width, msg->height, msg->encoding, msg->is_bigendian != 0, msg->step,
                      std::string_view(reinterpret_cast<const char*>(msg->data.data()),
                                       msg->data.size()));
                });
              }));
    }
  }

  // A rig camera's image at `stamp_ns`, decoded by `decode` (raw or compressed).
  void OnRigImage(size_t c, int64_t stamp_ns, const std::function<cv::Mat()>& decode) {
    cv::Mat image;
    try {
      image = decode();
    } catch (const std::exception& e) {
      ROS_ERROR_THROTTLE(5.0, "visloc: %s image refused: %s", rig_[c]->ns.c_str(), e.what());
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto& images = rig_[c]->images;
      images.emplace_back(stamp_ns, std::move(image));
      if (images.size() > 10) images.pop_front();
      sync_->gate().OnCamera(c, stamp_ns, WallNowS());
    }
    SendReady();
  }

  // The rig's further cameras on the session's body (the IMU's frame with use_imu, else the
  // reference camera's), from their camera_info and TF. False while one is not known yet.
  bool SetRigCameras(const std::string& reference_frame) {
    const std::string body_frame = use_imu_ ? imu_frame_ : reference_frame;
    std::vector<v1::RigCamera> cameras;
    for (const auto& camera : rig_) {
      if (!camera->info || body_frame.empty()) {
        PublishStatus("waiting for " + camera->ns + "/camera_info");
        return false;
      }
      v1::RigCamera& out = cameras.emplace_back();
      out.set_name(camera->ns);
      try {
        const ros_msg::CameraInfoMessage info = CameraInfoFromRos(*camera->info);
        ToProto(ros_msg::CameraFromInfo(info, camera->ns + "/camera_info"), out.mutable_camera());
        const auto t =
            tf_buffer_.lookupTransform(body_frame, camera->info->header.frame_id, ros::Time(0));
        ToProto(FromRos(t.transform), out.mutable_body_from_cam());
      } catch (const tf2::TransformException& e) {
        ROS_WARN_THROTTLE(5.0, "visloc: no TF %s -> %s yet: %s", body_frame.c_str(),
                          camera->info->header.frame_id.c_str(), e.what());
        return false;
      }
    }
    options_.rig_cameras = std::move(cameras);
    return true;
  }

  // An image waits (sensor_sync.h) until its odometry and IMU have come; before camera_info,
  // the newest one is kept for the session's first frame.
  void Receive(int64_t stamp_ns, vc::Frame frame) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++images_received_;
      frame.timestamp_ns = stamp_ns;
      if (!session_) {
        before_session_ = std::move(frame);
        return;
      }
      sync_->Add(stamp_ns, std::move(frame), WallNowS());
    }
    SendReady();
  }

  // Sends the images whose sensors have caught up (or waited long enough), in the order they
  // came: one sender at a time, so two callback threads never swap two frames.
  void SendReady() {
    std::lock_guard<std::mutex> one_sender(send_mutex_);
    std::vector<vc::Frame> ready;
    vc::Session* session = nullptr;  // Lives as long as the node.
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!session_) return;
      ready = sync_->TakeReady(WallNowS());
      for (vc::Frame& frame : ready) AttachSensors(frame);
      session = session_.get();
    }
    std::string why_not;
    for (const vc::Frame& frame : ready) {
      // Outside mutex_: the session may report a dropped frame (OnEvent) from this thread.
      if (!session->Submit(frame, &why_not)) {
        ROS_WARN_THROTTLE(5.0, "visloc: frame not sent: %s", why_not.c_str());
      }
    }
  }

  // Adds odometry, IMU and a pending hint to a frame about to be sent.
  void AttachSensors(vc::Frame& frame) {
    const int64_t stamp_ns = frame.timestamp_ns;
    if (use_odometry_) {
      // Interpolated at the image's own stamp, never an earlier sample in its place: that would
      // leave a frame's motion out of the prior. Without it (the wait ran out) the engine
      // predicts from its velocity for this frame.
      if (const auto odom_from_child = odometry_.At(stamp_ns)) {
        ToProto(*odom_from_child * BaseFromCamera(), &frame.odom_from_cam.emplace());
      } else {
        ++frames_without_odometry_;
        ROS_WARN_THROTTLE(5.0, "visloc: no odometry at an image's stamp within %.2f s: sent "
                          "without it", sensor_wait_s_);
      }
    }
    if (use_imu_) {
      // The samples between the previous frame and this one; later ones wait for the next.
      auto later = std::stable_partition(imu_.begin(), imu_.end(), [&](const v1::ImuSample& s) {
        return s.timestamp_ns() <= stamp_ns;
      });
      for (auto it = imu_.begin(); it != later; ++it) {
        if (it->timestamp_ns() > last_imu_frame_ns_) frame.imu.push_back(*it);
      }
      imu_.erase(imu_.begin(), later);
      last_imu_frame_ns_ = stamp_ns;
      imu_samples_sent_ += frame.imu.size();
    }
    // Each further camera's image of the same moment (nearest within the tolerance), or none.
    constexpr int64_t kRigToleranceNs = 5'000'000;
    for (const auto& camera : rig_) {
      vc::RigFrameImage& rig_image = frame.rig_images.emplace_back();
      auto& images = camera->images;
      auto best = images.end();
      for (auto it = images.begin(); it != images.end(); ++it) {
        const int64_t offset = std::abs(it->first - stamp_ns);
        if (offset <= kRigToleranceNs &&
            (best == images.end() || offset < std::abs(best->first - stamp_ns))) {
          best = it;
        }
      }
      if (best == images.end()) continue;
      rig_image.timestamp_ns = best->first;
      rig_image.image = best->second;
      images.erase(images.begin(), std::next(best));  // Older ones go with it.
    }
    if (pending_hint_) {
      frame.map_from_cam_hint = *pending_hint_;
      pending_hint_.reset();
    }
    last_frame_ = frame;
  }

  // The camera's pose on the odometry's child frame, from TF (static on a robot); identity
  // when the odometry tracks the camera's own frame.
  Rigid3d BaseFromCamera() {
    if (odom_child_frame_.empty() || odom_child_frame_ == camera_frame_) return Rigid3d::Identity();
    if (base_from_camera_) return *base_from_camera_;
    try {
      const auto t = tf_buffer_.lookupTransform(odom_child_frame_, camera_frame_, ros::Time(0));
      base_from_camera_ = FromRos(t.transform);
      return *base_from_camera_;
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(5.0, "visloc: no TF %s -> %s yet (%s): odometry taken as the camera's",
                        odom_child_frame_.c_str(), camera_frame_.c_str(), e.what());
      return Rigid3d::Identity();
    }
  }

  void OnEvent(const vc::Event& event) {
    using Kind = vc::Event::Kind;
    std::lock_guard<std::mutex> lock(mutex_);
    if (event.kind == Kind::kLinkState) {
      link_state_ = vc::LinkStateName(event.link_state);
      if (event.link_state != vc::LinkState::kConnected) {
        PublishStatus(StrCatLink(event));
        ROS_WARN("visloc: link %s: %s", link_state_.c_str(), event.detail.c_str());
      }
      return;
    }
    if (event.kind == Kind::kDropped || event.kind == Kind::kUndelivered) {
      ++frames_dropped_;
      return;
    }
    if (event.kind == Kind::kLate) {
      ++frames_late_;  // Too old to steer on: not published.
      return;
    }
    ++frames_answered_;
    last_response_ = event.response;
    last_latency_ms_ = event.latency_ms;
    const std::string status = v1::Status_Name(event.response.status());
    if (status != last_status_) PublishStatus(status);
    if (!IsPublishable(event.response)) return;
    ++poses_published_;
    const Rigid3d map_from_cam = PublishedPose(event.response, site_frame_);
    PublishPose(event.timestamp_ns, map_from_cam,
                std::vector<double>(event.response.covariance().begin(),
                                    event.response.covariance().end()));
    if (publish_tf_) PublishTransform(event.timestamp_ns, map_from_cam);
  }

  std::string StrCatLink(const vc::Event& event) const {
    return "link " + link_state_ + (event.detail.empty() ? "" : ": " + event.detail);
  }

  void PublishPose(int64_t stamp_ns, const Rigid3d& map_from_cam,
                   const std::vector<double>& covariance_cam) {
    geometry_msgs::PoseWithCovarianceStamped msg;
    msg.header.stamp = StampOf(stamp_ns);
    msg.header.frame_id = map_frame_;
    ToRos(map_from_cam, &msg.pose.pose);
    const auto covariance = CovarianceInMapFrame(map_from_cam, covariance_cam);
    std::copy(covariance.begin(), covariance.end(), msg.pose.covariance.begin());
    pose_pub_.publish(msg);
  }

  // REP 105: with odometry, map -> odom (the correction of the odometry's drift); without,
  // map -> camera.
  void PublishTransform(int64_t stamp_ns, const Rigid3d& map_from_cam) {
    geometry_msgs::TransformStamped t;
    t.header.stamp = StampOf(stamp_ns);
    t.header.frame_id = map_frame_;
    // map -> odom needs the odometry at the image's own stamp, interpolated, never an older
    // sample: by the time the answer is back, the odometry has usually caught up.
    const auto odom_from_child = use_odometry_ ? odometry_.At(stamp_ns) : std::nullopt;
    if (odom_from_child && !odom_frame_.empty()) {
      t.child_frame_id = odom_frame_;
      ToRos(MapFromOdom(map_from_cam, *odom_from_child * BaseFromCamera()), &t.transform);
    } else if (!use_odometry_) {
      t.child_frame_id = camera_frame_;
      ToRos(map_from_cam, &t.transform);
    } else {
      // Odometry expected but not there yet: wait for it (a bounded while), never guess.
      waiting_for_odometry_.push_back({stamp_ns, map_from_cam});
      if (waiting_for_odometry_.size() > 10) {
        waiting_for_odometry_.pop_front();
        ROS_WARN_THROTTLE(5.0,
                          "visloc: no odometry at the images' stamps: no map -> odom for them");
      }
      return;
    }
    tf_broadcaster_.sendTransform(t);
  }

  void PublishStatus(const std::string& status) {
    last_status_ = status;
    std_msgs::String msg;
    msg.data = status;
    status_pub_.publish(msg);
  }

  void PublishDiagnostics() {
    std::lock_guard<std::mutex> lock(mutex_);
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.name = "visloc: localization";
    status.hardware_id = options_.server;
    const v1::Status engine = last_response_.status();
    status.level = failed_ || engine == v1::STATUS_LOST || engine == v1::STATUS_ERROR
                       ? diagnostic_msgs::DiagnosticStatus::ERROR
                   : IsPublishable(last_response_) && link_state_ == "connected"
                       ? diagnostic_msgs::DiagnosticStatus::OK
                       : diagnostic_msgs::DiagnosticStatus::WARN;
    status.message = last_status_;
    auto add = [&](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      status.values.push_back(kv);
    };
    add("map", options_.map_name);
    add("link", link_state_);
    add("status", v1::Status_Name(engine));
    add("inliers", std::to_string(last_response_.stats().inliers()));
    add("putatives", std::to_string(last_response_.stats().putatives()));
    add("inlier_ratio", std::to_string(last_response_.stats().inlier_ratio()));
    add("reproj_rmse_px", std::to_string(last_response_.stats().reproj_rmse_px()));
    add("latency_ms", std::to_string(last_latency_ms_));
    add("images_received", std::to_string(images_received_));
    add("frames_answered", std::to_string(frames_answered_));
    add("poses_published", std::to_string(poses_published_));
    add("frames_dropped", std::to_string(frames_dropped_));
    add("frames_late", std::to_string(frames_late_));
    add("imu_samples_sent", std::to_string(imu_samples_sent_));
    add("frames_without_odometry", std::to_string(frames_without_odometry_));
    array.status.push_back(status);
    diagnostics_pub_.publish(array);
  }

  bool OnRelocalize(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    vc::Frame frame;
    vc::SessionOptions options;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!last_frame_) {
        res.success = false;
        res.message = session_ ? "no image received yet" : "no camera_info received yet";
        return true;
      }
      frame = *last_frame_;
      options = options_;
    }
    try {
      const v1::RelocalizeResponse answer =
          vc::Relocalize(options, frame, std::chrono::milliseconds(5000));
      res.success = answer.localized();
      if (!answer.localized()) {
        res.message = "not localized: " + std::to_string(answer.candidates_size()) +
                      " candidates, none verified";
        return true;
      }
      const Rigid3d map_from_cam = PublishedPose(answer, site_frame_);
      std::lock_guard<std::mutex> lock(mutex_);
      pending_hint_ = answer.map_from_cam();
      PublishPose(frame.timestamp_ns, map_from_cam,
                  std::vector<double>(answer.covariance().begin(), answer.covariance().end()));
      std::ostringstream text;
      text << "localized at (" << map_from_cam.translation.x() << ", "
           << map_from_cam.translation.y() << ", " << map_from_cam.translation.z() << ") m with "
           << answer.inliers() << " inliers in " << answer.ms() << " ms";
      res.message = text.str();
    } catch (const std::exception& e) {
      res.success = false;
      res.message = e.what();
    }
    return true;
  }

  ros::NodeHandle& nh_;
  ros::NodeHandle& pnh_;
  image_transport::ImageTransport transport_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  ros::Publisher pose_pub_, status_pub_, diagnostics_pub_;
  ros::Subscriber info_sub_, compressed_sub_, odom_sub_, imu_sub_;
  image_transport::Subscriber image_sub_;
  ros::ServiceServer relocalize_srv_;
  ros::WallTimer diagnostics_timer_, sync_timer_;

  std::mutex send_mutex_;  // One SendReady at a time (taken before mutex_, never inside it).

  std::mutex mutex_;  // Guards everything below: ROS callbacks and the session's events.
  vc::SessionOptions options_;
  std::unique_ptr<vc::Session> session_;
  bool failed_ = false;
  std::string map_frame_, camera_frame_, camera_frame_override_;
  bool site_frame_ = true;
  bool compressed_ = false;  // ~transport:=compressed: every camera's CompressedImage topic.
  std::string odom_frame_, odom_child_frame_, imu_frame_;
  bool publish_tf_ = true, use_odometry_ = false, use_imu_ = false;
  double sensor_wait_s_ = 0.1;
  std::optional<SensorSync<vc::Frame>> sync_;  // Images waiting for their odometry and IMU.
  double first_camera_info_s_ = 0.0;  // Wall time, while waiting for the IMU.
  OdometryBuffer odometry_;
  std::optional<Rigid3d> base_from_camera_;
  std::vector<v1::ImuSample> imu_;  // Received, not yet sent (bounded).
  int64_t last_imu_frame_ns_ = INT64_MIN;
  std::optional<vc::Frame> last_frame_;
  std::optional<vc::Frame> before_session_;
  std::deque<StampedPose> waiting_for_odometry_;  // map_from_cam of answers ahead of odometry.  //
                                                  // The newest image before camera_info came.
  std::optional<v1::Pose> pending_hint_;
  // A rig's further cameras (~rig_cameras): their topics, camera_info and recent images.
  struct RigCameraTopics {
    std::string ns;
    std::optional<sensor_msgs::CameraInfo> info;
    std::deque<std::pair<int64_t, cv::Mat>> images;  // By stamp, the last few.
    ros::Subscriber info_sub, compressed_sub;
    image_transport::Subscriber image_sub;
  };
  std::vector<std::unique_ptr<RigCameraTopics>> rig_;
  v1::LocalizeResponse last_response_;
  std::string link_state_ = "connecting", last_status_;
  double last_latency_ms_ = 0.0;
  uint64_t images_received_ = 0, frames_answered_ = 0, poses_published_ = 0, frames_dropped_ = 0,
           frames_late_ = 0, imu_samples_sent_ = 0, frames_without_odometry_ = 0;
};

}  // namespace
}  // namespace visloc::ros_node

int main(int argc, char** argv) {
  ros::init(argc, argv, "visloc");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  try {
    // ~mode:=map streams a stereo camera to the server's mapper instead (mapping_node.h).
    if (pnh.param<std::string>("mode", "localize") == "map") {
      return visloc::ros_node::RunMappingNode(nh, pnh);
    }
    visloc::ros_node::LocalizationNode node(nh, pnh);
    // Two threads: image callbacks never wait behind a relocalize service call.
    ros::MultiThreadedSpinner spinner(2);
    spinner.spin();
  } catch (const std::exception& e) {
    ROS_FATAL("visloc: %s", e.what());
    return 1;
  }
  return 0;
}
