// The wire translation of cameras: both lenses round-trip, and a CameraModel from a client that
// predates lens_model (no field 8) still means a pinhole with radial-tangential distortion.

#include "proto/convert.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include <opencv2/imgproc.hpp>

#include "core/image/image_codec.h"
#include "core/util/check.h"
#include "core/util/worker_pool.h"

namespace visloc {
namespace {

TEST(CameraConvertTest, BothLensesRoundTrip) {
  for (const Camera& camera :
       {Camera(752, 480, 458.6, 457.3, 367.2, 248.4, Lens(-0.28, 0.07, 1e-4, 2e-5)),
        Camera(512, 512, 190.9, 190.9, 254.9, 256.9, Lens::Equidistant(3e-3, 7e-4, -2e-3, 2e-4)),
        Camera(320, 240, 160, 160, 159.5, 119.5)}) {
    v1::CameraModel wire;
    proto::ToProto(camera, &wire);
    const Camera back = proto::FromProto(wire, proto::WireLimits{});
    EXPECT_EQ(back.Params(), camera.Params());
    EXPECT_TRUE(back.lens() == camera.lens());
  }
}

TEST(CameraConvertTest, OlderClientsMeanRadialTangentialAndBadLensesAreNamed) {
  v1::CameraModel wire;  // As a client built before lens_model sends it.
  wire.set_width(320);
  wire.set_height(240);
  wire.set_fx(160);
  wire.set_fy(160);
  wire.set_cx(159.5);
  wire.set_cy(119.5);
  for (double k : {-0.1, 0.01, 0.0, 0.0}) wire.add_distortion(k);
  const std::string bytes = wire.SerializeAsString();
  v1::CameraModel old;
  ASSERT_TRUE(old.ParseFromString(bytes));
  EXPECT_EQ(proto::FromProto(old, proto::WireLimits{}).lens().model,
            LensModel::kRadialTangential);

  v1::CameraModel fisheye = wire;
  fisheye.set_lens_model(v1::EQUIDISTANT);
  fisheye.clear_distortion();
  EXPECT_THAT([&] { proto::FromProto(fisheye, proto::WireLimits{}); },
              ::testing::ThrowsMessage<InputError>(::testing::HasSubstr(
                  "an equidistant lens needs 4 distortion values (k1 k2 k3 k4), got 0")));
  v1::CameraModel unknown = wire;
  unknown.set_lens_model(static_cast<v1::LensModel>(7));
  EXPECT_THROW(proto::FromProto(unknown, proto::WireLimits{}), InputError);
  v1::CameraModel nan = wire;
  nan.set_distortion(1, std::nan(""));
  EXPECT_THROW(proto::FromProto(nan, proto::WireLimits{}), InputError);
}

// What the server must refuse at the door (issue 23's list): each refusal names the field and
// the allowed range, and none carries a source location.
class WireValidationTest : public ::testing::Test {
 protected:
  static v1::CameraModel GoodCamera() {
    v1::CameraModel c;
    proto::ToProto(Camera(320, 240, 160, 160, 159.5, 119.5), &c);
    return c;
  }
  static void ExpectRefused(const std::function<void()>& convert, const std::string& field) {
    try {
      convert();
      ADD_FAILURE() << field << " was accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr(field));
      EXPECT_THAT(e.what(), ::testing::HasSubstr("allowed"));
      EXPECT_THAT(e.what(), ::testing::Not(::testing::HasSubstr(".cc")));
    }
  }
};

TEST_F(WireValidationTest, ARigSessionDeclaresItsCamerasAndEachFrameCarriesTheirImages) {
  v1::SessionStart start;
  *start.mutable_camera() = GoodCamera();
  v1::RigCamera* rear = start.add_rig_cameras();
  *rear->mutable_camera() = GoodCamera();
  const Rigid3d body_from_rear(RotationFromRollPitchYaw(0, 0, M_PI), Eigen::Vector3d(-0.1, 0, 0));
  proto::ToProto(body_from_rear, rear->mutable_body_from_cam());
  const CameraRig rig = proto::RigFromProto(start, proto::WireLimits{});
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_FALSE(rig.body_is_gyro_frame);  // No options.body_from_cam: the reference is the body.
  EXPECT_TRUE(ApproxEqual(rig.CamFromReference(1), body_from_rear.Inverse(), 1e-12, 1e-9));

  const cv::Mat grey(240, 320, CV_8UC1, cv::Scalar(90));
  std::vector<uint8_t> png;
  std::string error;
  ASSERT_TRUE(image::EncodePng(grey, 1, &png, &error)) << error;
  v1::Frame frame;
  frame.set_timestamp_ns(1000);
  frame.set_encoded(std::string(png.begin(), png.end()));
  EXPECT_THAT(
      [&] { proto::FromProto(frame, rig); },
      ::testing::ThrowsMessage<InputError>(::testing::HasSubstr(
          "the frame carries 0 rig images for a rig of 2 cameras (1 besides the reference)")));
  v1::RigImage* image = frame.add_rig_images();
  image->set_timestamp_ns(1001);
  image->set_encoded(std::string(png.begin(), png.end()));
  const FrameInput input = proto::FromProto(frame, rig);
  ASSERT_EQ(input.rig_images.size(), 1u);
  EXPECT_EQ(input.rig_images[0].timestamp_ns, 1001);
  EXPECT_EQ(input.rig_images[0].image.cols, 320);
  // A camera that gave no image this time: an empty one; a bad one is named.
  image->clear_encoded();
  EXPECT_TRUE(proto::FromProto(frame, rig).rig_images[0].image.empty());
  image->set_encoded("not an image");
  EXPECT_THAT([&] { proto::FromProto(frame, rig); },
              ::testing::ThrowsMessage<InputError>(
                  ::testing::HasSubstr("rig image 1: image (12 bytes): not a PNG or JPEG")));
  // Each rig camera is placed, and a rig has at most eight cameras.
  rear->clear_body_from_cam();
  EXPECT_THAT([&] { proto::RigFromProto(start, proto::WireLimits{}); },
              ::testing::ThrowsMessage<InputError>(
                  ::testing::HasSubstr("start.rig_cameras[0] has no body_from_cam")));
  proto::ToProto(body_from_rear, rear->mutable_body_from_cam());
  for (int i = 0; i < 7; ++i) *start.add_rig_cameras() = *rear;
  EXPECT_THAT([&] { proto::RigFromProto(start, proto::WireLimits{}); },
              ::testing::ThrowsMessage<InputError>(::testing::HasSubstr(
                  "start.rig_cameras: 8 cameras; at most 7 besides the reference")));
}

// A server decodes a rig frame's images side by side (Localizer::ForEachOnRigThreads): what it
// gets, and the refusals, are what decoding them one after the other gives.
TEST_F(WireValidationTest, ARigFramesImagesDecodedSideBySideAreTheOnesDecodedInTurn) {
  v1::SessionStart start;
  *start.mutable_camera() = GoodCamera();
  for (int c = 1; c <= 3; ++c) {
    v1::RigCamera* camera = start.add_rig_cameras();
    *camera->mutable_camera() = GoodCamera();
    proto::ToProto(Rigid3d(RotationFromRollPitchYaw(0, 0, c * M_PI / 2), Eigen::Vector3d::Zero()),
                   camera->mutable_body_from_cam());
  }
  const CameraRig rig = proto::RigFromProto(start, proto::WireLimits{});
  const auto jpeg = [](int grey) {
    cv::Mat image(240, 320, CV_8UC1, cv::Scalar(grey));
    cv::circle(image, cv::Point(40 + grey / 2, 120), 30, cv::Scalar(255 - grey), -1);
    std::vector<uint8_t> bytes;
    std::string error;
    EXPECT_TRUE(image::EncodeJpeg(image, 95, &bytes, &error)) << error;
    return std::string(bytes.begin(), bytes.end());
  };
  v1::Frame frame;
  frame.set_timestamp_ns(1000);
  frame.set_encoded(jpeg(20));
  proto::ToProto(Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3)),
                 frame.mutable_odom_from_cam());
  for (int c = 1; c <= 3; ++c) {
    v1::RigImage* image = frame.add_rig_images();
    image->set_timestamp_ns(1000 + c);
    if (c != 2) image->set_encoded(jpeg(20 + 60 * c));  // Camera 2 gave none this time.
  }
  WorkerPool pool(3);
  const proto::ParallelFor side_by_side = [&](int n, const std::function<void(int)>& fn) {
    pool.ForEachClaimed(n, 4, fn);
  };
  const FrameInput in_turn = proto::FromProto(frame, rig);
  const FrameInput parallel = proto::FromProto(frame, rig, side_by_side);
  EXPECT_EQ(parallel.timestamp_ns, 1000);
  ASSERT_TRUE(parallel.odom_from_cam.has_value());
  EXPECT_TRUE(parallel.odom_from_cam->translation.isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_EQ(cv::norm(parallel.image, in_turn.image, cv::NORM_INF), 0.0);
  ASSERT_EQ(parallel.rig_images.size(), 3u);
  for (size_t c = 0; c < 3; ++c) {
    EXPECT_EQ(parallel.rig_images[c].timestamp_ns, in_turn.rig_images[c].timestamp_ns);
    ASSERT_EQ(parallel.rig_images[c].image.empty(), c == 1) << "rig image " << c + 1;
    if (c != 1) {
      EXPECT_EQ(cv::norm(parallel.rig_images[c].image, in_turn.rig_images[c].image, cv::NORM_INF),
                0.0);
    }
  }
  // Refusals: the first bad image in the rig's order is named, as in turn.
  frame.mutable_rig_images(2)->set_encoded("not an image");
  for (const proto::ParallelFor& how : {proto::ParallelFor(), side_by_side}) {
    EXPECT_THAT([&] { proto::FromProto(frame, rig, how); },
                ::testing::ThrowsMessage<InputError>(
                    ::testing::HasSubstr("rig image 3: image (12 bytes): not a PNG or JPEG")));
  }
  frame.set_encoded("not a reference image either");
  for (const proto::ParallelFor& how : {proto::ParallelFor(), side_by_side}) {
    EXPECT_THAT([&] { proto::FromProto(frame, rig, how); },
                ::testing::ThrowsMessage<InputError>(
                    ::testing::AllOf(::testing::HasSubstr("image (28 bytes): not a PNG or JPEG"),
                                     ::testing::Not(::testing::HasSubstr("rig image")))));
  }
  frame.set_encoded(jpeg(20));
  frame.mutable_rig_images()->RemoveLast();
  for (const proto::ParallelFor& how : {proto::ParallelFor(), side_by_side}) {
    EXPECT_THAT([&] { proto::FromProto(frame, rig, how); },
                ::testing::ThrowsMessage<InputError>(
                    ::testing::HasSubstr("the frame carries 2 rig images for a rig of 4 cameras")));
  }

  // The Relocalize RPC's images of a rig, the same way.
  v1::RelocalizeRequest request;
  request.set_encoded_image(jpeg(20));
  for (int c = 1; c <= 3; ++c) {
    v1::RigImage* image = request.add_rig_images();
    if (c != 2) image->set_encoded(jpeg(20 + 60 * c));
  }
  const std::vector<cv::Mat> images_in_turn = proto::RigImagesFromProto(request, rig);
  const std::vector<cv::Mat> images = proto::RigImagesFromProto(request, rig, side_by_side);
  ASSERT_EQ(images.size(), 4u);
  for (size_t c = 0; c < 4; ++c) {
    ASSERT_EQ(images[c].empty(), c == 2) << "camera " << c;
    if (c != 2) {
      EXPECT_EQ(cv::norm(images[c], images_in_turn[c], cv::NORM_INF), 0.0);
    }
  }
  request.mutable_rig_images(0)->set_encoded("not an image");
  EXPECT_THAT([&] { proto::RigImagesFromProto(request, rig, side_by_side); },
              ::testing::ThrowsMessage<InputError>(
                  ::testing::HasSubstr("rig image 1: image (12 bytes): not a PNG or JPEG")));
}

TEST_F(WireValidationTest, SessionOptionsOutOfRangeAreRefusedByName) {
  const auto refused = [](const std::function<void(v1::SessionOptions*)>& set,
                          const std::string& field) {
    v1::SessionOptions options;
    set(&options);
    ExpectRefused([&] { proto::FromProto(options); }, field);
  };
  refused([](v1::SessionOptions* o) { o->set_camera_height_m(std::nan("")); },
          "options.camera_height_m");
  refused([](v1::SessionOptions* o) { o->set_camera_height_m(1e300); }, "options.camera_height_m");
  refused([](v1::SessionOptions* o) { o->set_probability_threshold(-1); },
          "options.probability_threshold");
  refused([](v1::SessionOptions* o) { o->set_ransac_max_error_px(-5); },
          "options.ransac_max_error_px");
  refused([](v1::SessionOptions* o) { o->set_visibility_k(4000000000u); }, "options.visibility_k");
  refused([](v1::SessionOptions* o) { o->set_ransac_max_iterations(4000000000u); },
          "options.ransac_max_iterations");
  refused([](v1::SessionOptions* o) { o->set_prediction(static_cast<v1::PredictionMode>(9)); },
          "options.prediction");
  // In range, they are taken.
  v1::SessionOptions fine;
  fine.set_camera_height_m(0.3);
  fine.set_probability_threshold(0.5);
  fine.set_ransac_max_error_px(3);
  fine.set_visibility_k(20);
  const LocalizerOptions options = proto::FromProto(fine);
  EXPECT_EQ(options.tracker.visibility.k, 20);
  EXPECT_EQ(options.motion.height_m, 0.3);
}

TEST_F(WireValidationTest, ImplausibleIntrinsicsAreRefusedByName) {
  v1::CameraModel tiny_focal = GoodCamera();
  tiny_focal.set_fx(1e-9);
  ExpectRefused([&] { proto::FromProto(tiny_focal, proto::WireLimits{}); }, "camera.fx");
  v1::CameraModel far_centre = GoodCamera();
  far_centre.set_cx(-1e9);
  ExpectRefused([&] { proto::FromProto(far_centre, proto::WireLimits{}); }, "camera.cx");
  v1::CameraModel nan_fy = GoodCamera();
  nan_fy.set_fy(std::nan(""));
  ExpectRefused([&] { proto::FromProto(nan_fy, proto::WireLimits{}); }, "camera.fy");
}

TEST_F(WireValidationTest, PresentPosesMustHaveAUsableQuaternion) {
  const Camera camera(8, 8, 8, 8, 3.5, 3.5);
  v1::Frame frame;
  frame.mutable_raw()->set_width(8);
  frame.mutable_raw()->set_height(8);
  frame.mutable_raw()->set_pixels(std::string(64, '\x80'));
  // Present but all zeros: refused, not taken for "no odometry".
  frame.mutable_odom_from_cam()->set_tx(1.0);
  EXPECT_THAT([&] { proto::FromProto(frame, camera); },
              ::testing::ThrowsMessage<InputError>(
                  ::testing::HasSubstr("frame.odom_from_cam: quaternion (w 0, x 0, y 0, z 0)")));
  // A quaternion off unit length is normalized.
  frame.mutable_odom_from_cam()->set_qw(2.0);
  const FrameInput input = proto::FromProto(frame, camera);
  ASSERT_TRUE(input.odom_from_cam.has_value());
  EXPECT_NEAR(input.odom_from_cam->rotation.w(), 1.0, 1e-12);
  frame.mutable_map_from_cam_hint()->set_qw(std::nan(""));
  EXPECT_THROW(proto::FromProto(frame, camera), InputError);
  v1::SessionOptions options;
  options.mutable_body_from_cam()->set_tz(0.1);
  EXPECT_THAT([&] { proto::FromProto(options); },
              ::testing::ThrowsMessage<InputError>(::testing::HasSubstr("options.body_from_cam")));
}

}  // namespace
}  // namespace visloc
