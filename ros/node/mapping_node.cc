#include "ros/node/mapping_node.h"

#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <geometry_msgs/PoseStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include "proto/geometry_convert.h"
#include "ros/messages/ros_messages.h"
#include "ros/node/ros_camera_info.h"
#include "visloc/client/mapping_session.h"

namespace visloc::ros_node {
namespace {

namespace vc = visloc::client;

constexpr int64_t kPairWindowNs = 2'000'000'000;  // An unpaired image older than this is dropped.
constexpr size_t kMaxQueued = 600;                // Paired frames waiting for the link.

cv::Mat Decode(const sensor_msgs::Image& msg) {
  return ros_msg::DecodeRawImage(
      msg.width, msg.height, msg.encoding, msg.is_bigendian != 0, msg.step,
      std::string_view(reinterpret_cast<const char*>(msg.data.data()), msg.data.size()));
}

class MappingNode {
 public:
  MappingNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh) {
    options_.server = pnh_.param<std::string>("server", "127.0.0.1:50051");
    options_.map_name = pnh_.param<std::string>("map", "");
    if (options_.map_name.empty()) throw std::runtime_error("~map (the new map's name) is not set");
    options_.robot_id = pnh_.param<std::string>("robot_id", ros::this_node::getName());
    options_.credentials.token = pnh_.param<std::string>("token", "");
    options_.mapping.set_replace(pnh_.param<bool>("replace", false));
    map_frame_ = pnh_.param<std::string>("map_frame", "map");
    status_pub_ = pnh_.advertise<std_msgs::String>("status", 10, /*latch=*/true);
    pose_pub_ = pnh_.advertise<geometry_msgs::PoseStamped>("mapping_pose", 10);
    left_info_sub_ = nh_.subscribe("left/camera_info", 1, &MappingNode::OnLeftInfo, this);
    right_info_sub_ = nh_.subscribe("right/camera_info", 1, &MappingNode::OnRightInfo, this);
    left_sub_ = nh_.subscribe("left/image", 50, &MappingNode::OnLeft, this);
    right_sub_ = nh_.subscribe("right/image", 50, &MappingNode::OnRight, this);
    finish_srv_ = pnh_.advertiseService("finish_map", &MappingNode::OnFinish, this);
    sender_ = std::thread([this] { Send(); });
    Status("waiting for both cameras' camera_info");
  }

  ~MappingNode() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    ready_.notify_all();
    sender_.join();
  }

 private:
  void OnLeftInfo(const sensor_msgs::CameraInfo& msg) { SetInfo(msg, &left_info_); }
  void OnRightInfo(const sensor_msgs::CameraInfo& msg) { SetInfo(msg, &right_info_); }

  void SetInfo(const sensor_msgs::CameraInfo& msg,
               std::optional<ros_msg::CameraInfoMessage>* info) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!*info) *info = CameraInfoFromRos(msg);
    ready_.notify_all();
  }

  void OnLeft(const sensor_msgs::ImageConstPtr& msg) { Pair(*msg, &left_, &right_, true); }
  void OnRight(const sensor_msgs::ImageConstPtr& msg) { Pair(*msg, &right_, &left_, false); }

  // Holds an image until its partner of the same stamp arrives, then queues the pair.
  void Pair(const sensor_msgs::Image& msg, std::map<int64_t, cv::Mat>* mine,
            std::map<int64_t, cv::Mat>* other, bool is_left) {
    const int64_t stamp_ns = static_cast<int64_t>(msg.header.stamp.toNSec());
    cv::Mat image;
    try {
      image = Decode(msg);
    } catch (const std::exception& e) {
      ROS_ERROR_THROTTLE(5.0, "visloc: image refused: %s", e.what());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    const auto partner = other->find(stamp_ns);
    if (partner == other->end()) {
      (*mine)[stamp_ns] = image;
      for (auto* waiting : {mine, other}) {  // Unpaired and old: its partner is not coming.
        while (!waiting->empty() && waiting->begin()->first < stamp_ns - kPairWindowNs) {
          waiting->erase(waiting->begin());
          ++unpaired_;
        }
      }
      return;
    }
    vc::StereoFrame frame;
    frame.timestamp_ns = stamp_ns;
    frame.left = is_left ? image : partner->second;
    frame.right = is_left ? partner->second : image;
    other->erase(partner);
    if (queue_.size() >= kMaxQueued) {
      queue_.pop_front();
      ++dropped_;
    }
    queue_.push_back(std::move(frame));
    ready_.notify_all();
  }

  // The sender thread: opens the job once both camera_infos are known, then streams the queue.
  void Send() {
    for (;;) {
      vc::StereoFrame frame;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        ready_.wait(lock, [&] {
          return stopping_ || (!session_ && !failed_ && left_info_ && right_info_) ||
                 (session_ && !queue_.empty());
        });
        if (stopping_) return;
        if (!session_) {
          lock.unlock();
          Open();
          continue;
        }
        frame = std::move(queue_.front());
        queue_.pop_front();
        submitting_ = true;
      }
      std::string why;
      const bool sent = session_->Submit(frame, &why);
      if (sent) Report();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        submitting_ = false;
      }
      if (!sent) Fail(why);
      ready_.notify_all();
    }
  }

  void Open() {
    try {
      const ros_msg::CameraInfoMessage left = *left_info_, right = *right_info_;
      options_.rig.Clear();
      proto::ToProto(ros_msg::CameraFromInfo(left, nh_.resolveName("left/camera_info")),
                     options_.rig.mutable_left());
      proto::ToProto(ros_msg::CameraFromInfo(right, nh_.resolveName("right/camera_info")),
                     options_.rig.mutable_right());
      proto::ToProto(Rigid3d::Identity(), options_.rig.mutable_body_from_left());
      proto::ToProto(ros_msg::LeftFromRight(left, right), options_.rig.mutable_body_from_right());
      auto session = vc::MappingSession::Open(options_);
      std::lock_guard<std::mutex> lock(mutex_);
      session_ = std::move(session);
      ROS_INFO("visloc: mapping '%s' on %s (job %llu)", options_.map_name.c_str(),
               options_.server.c_str(), static_cast<unsigned long long>(session_->job_id()));
    } catch (const std::exception& e) {
      Fail(e.what());
    }
    Status("mapping");
  }

  void Fail(const std::string& why) {
    ROS_ERROR("visloc: mapping '%s': %s", options_.map_name.c_str(), why.c_str());
    std::lock_guard<std::mutex> lock(mutex_);
    failed_ = true;
    failure_ = why;
    queue_.clear();
    status_ = "failed: " + why;
    Publish(status_);
  }

  // The answers so far: the status line and the left camera's pose as mapped.
  void Report() {
    for (const vc::MappingAnswer& answer : session_->TakeAnswers()) {
      const v1::MappingProgress& p = answer.progress;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        ++answered_;
        keyframes_ = p.keyframes();
        points_ = p.points();
      }
      if (p.has_pose()) {
        geometry_msgs::PoseStamped pose;
        pose.header.stamp.fromNSec(static_cast<uint64_t>(p.timestamp_ns()));
        pose.header.frame_id = map_frame_;
        const Rigid3d map_from_cam = proto::FromProto(p.map_from_cam(), "map_from_cam");
        pose.pose.position.x = map_from_cam.translation.x();
        pose.pose.position.y = map_from_cam.translation.y();
        pose.pose.position.z = map_from_cam.translation.z();
        pose.pose.orientation.w = map_from_cam.rotation.w();
        pose.pose.orientation.x = map_from_cam.rotation.x();
        pose.pose.orientation.y = map_from_cam.rotation.y();
        pose.pose.orientation.z = map_from_cam.rotation.z();
        pose_pub_.publish(pose);
      }
    }
    Status("mapping");
  }

  void Status(const std::string& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (failed_) return;
    const vc::MappingSessionStats stats = session_ ? session_->stats() : vc::MappingSessionStats{};
    status_ = state + ": " + std::to_string(answered_) + " frames answered, " +
              std::to_string(keyframes_) + " keyframes, " + std::to_string(points_) + " points, " +
              std::to_string(stats.lost) + " lost, " + std::to_string(unpaired_) + " unpaired, " +
              std::to_string(dropped_) + " dropped, " + std::to_string(stats.resumes) + " resumes";
    Publish(status_);
  }

  void Publish(const std::string& text) {
    std_msgs::String msg;
    msg.data = text;
    status_pub_.publish(msg);
  }

  // Waits for the queue to be sent, then ends the run and reports what was published.
  bool OnFinish(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool drained = ready_.wait_for(lock, std::chrono::seconds(60), [&] {
      return failed_ || (session_ && queue_.empty() && !submitting_);
    });
    if (failed_ || !session_ || !drained) {
      response.success = false;
      response.message = failed_ ? failure_ : "no frames were mapped yet";
      return true;
    }
    stopping_ = true;  // The sender stops; nothing more is submitted.
    lock.unlock();
    ready_.notify_all();
    try {
      const v1::MappingProgress done = session_->Finish();
      response.success = true;
      response.message = "published '" + done.map().name() +
                         "': " + std::to_string(done.frame_index()) + " frames, " +
                         std::to_string(done.keyframes()) + " keyframes, " +
                         std::to_string(done.points()) + " points";
    } catch (const std::exception& e) {
      response.success = false;
      response.message = e.what();
    }
    Publish(response.message);
    ROS_INFO("visloc: %s", response.message.c_str());
    return true;
  }

  ros::NodeHandle& nh_;
  ros::NodeHandle& pnh_;
  ros::Publisher status_pub_, pose_pub_;
  ros::Subscriber left_info_sub_, right_info_sub_, left_sub_, right_sub_;
  ros::ServiceServer finish_srv_;
  vc::MappingSessionOptions options_;
  std::string map_frame_;
  std::thread sender_;

  std::mutex mutex_;  // Guards what follows: ROS callbacks, the sender thread, the service.
  std::condition_variable ready_;
  std::optional<ros_msg::CameraInfoMessage> left_info_, right_info_;
  std::map<int64_t, cv::Mat> left_, right_;  // Waiting for their partners, by stamp.
  std::deque<vc::StereoFrame> queue_;
  std::unique_ptr<vc::MappingSession> session_;
  bool failed_ = false, stopping_ = false, submitting_ = false;
  std::string failure_, status_;
  uint64_t answered_ = 0, unpaired_ = 0, dropped_ = 0, keyframes_ = 0, points_ = 0;
};

}  // namespace

int RunMappingNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
  MappingNode node(nh, pnh);
  // Two threads: images keep arriving while the finish service waits for the server.
  ros::MultiThreadedSpinner spinner(2);
  spinner.spin();
  return 0;
}

}  // namespace visloc::ros_node
