// The wire translation of cameras: both lenses round-trip, and a CameraModel from a client that
// predates lens_model (no field 8) still means a pinhole with radial-tangential distortion.

#include "proto/convert.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "core/util/check.h"

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

}  // namespace
}  // namespace visloc
