// A map's summary survives the wire: what `visloc map info` prints of a remote map is what it
// prints of the file.

#include "proto/map_info_convert.h"

#include <gtest/gtest.h>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"
#include "core/util/temp_dir.h"
#include "mapstore/map_store.h"

namespace visloc {
namespace {

TEST(MapInfoConvertTest, AMapsSummaryRoundTrips) {
  TempDir dir;
  Map map = MakeSyntheticMap({});
  map.metadata.disparity_correction = DisparityCorrection{-0.6, 1.2e-3};
  map.metadata.rig_error = RigError{0.0, 0.0};
  map.metadata.stereo_baseline_m = 0.110077;
  map.metadata.gravity =
      MapGravity{Eigen::Vector3d(0.6, -0.8, 0.0), 0.25, MapGravity::Source::kLevelRig};
  map.metadata.site =
      SiteAlignment{Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                            Eigen::Vector3d(10, -2, 0.5)),
                    5, 0.008, 0.015, "pairs spots.csv"};
  mapstore::SaveMap(map, dir.File("lab.db"));
  const mapstore::MapDirectory::Entry local = mapstore::MapDirectory(dir.path()).Describe("lab");
  ASSERT_TRUE(local.info.has_value()) << local.error;
  v1::MapInfo wire;
  proto::ToProto(local, &wire);
  const mapstore::MapDirectory::Entry remote = proto::FromProto(wire, "lab on server");
  ASSERT_TRUE(remote.info.has_value());
  const mapstore::MapInfo& a = *local.info;
  const mapstore::MapInfo& b = *remote.info;
  EXPECT_EQ(remote.name, "lab");
  EXPECT_EQ(b.path, "lab on server");
  EXPECT_EQ(b.file_bytes, a.file_bytes);
  EXPECT_EQ(b.schema_version, a.schema_version);
  EXPECT_EQ(b.metadata.name, "lab");  // A server's maps are named by their files.
  EXPECT_EQ(b.metadata.created_unix_s, a.metadata.created_unix_s);
  EXPECT_EQ(b.metadata.builder, a.metadata.builder);
  EXPECT_EQ(b.camera.Params(), a.camera.Params());
  EXPECT_EQ(b.camera.width(), a.camera.width());
  EXPECT_EQ(b.features.kind, a.features.kind);
  EXPECT_EQ(b.features.descriptor_type, a.features.descriptor_type);
  EXPECT_EQ(b.features.descriptor_dim, a.features.descriptor_dim);
  EXPECT_EQ(b.keyframes, a.keyframes);
  EXPECT_EQ(b.points, a.points);
  EXPECT_EQ(b.observations, a.observations);
  EXPECT_DOUBLE_EQ(b.mean_reproj_error_px, a.mean_reproj_error_px);
  EXPECT_TRUE(b.point_extent.isApprox(a.point_extent));
  EXPECT_TRUE(b.keyframe_extent.isApprox(a.keyframe_extent));
  EXPECT_EQ(b.kernel_learned, a.kernel_learned);
  EXPECT_EQ(b.kernel.default_k, a.kernel.default_k);
  EXPECT_EQ(b.vocabulary_words, a.vocabulary_words);
  EXPECT_EQ(b.memory_bytes, a.memory_bytes);
  ASSERT_TRUE(b.metadata.disparity_correction.has_value());
  EXPECT_EQ(b.metadata.disparity_correction->offset_px, -0.6);
  EXPECT_NEAR(b.metadata.disparity_correction->yaw_rad, 1.2e-3, 1e-15);
  ASSERT_TRUE(b.metadata.rig_error.has_value());  // An exact rig is not "none".
  EXPECT_EQ(*b.metadata.rig_error, RigError{});
  EXPECT_EQ(b.metadata.stereo_baseline_m, 0.110077);
  EXPECT_EQ(b.metadata.gravity, map.metadata.gravity);
  ASSERT_TRUE(b.metadata.site.has_value());
  EXPECT_EQ(b.metadata.site->pairs, 5);
  EXPECT_EQ(b.metadata.site->reference, "pairs spots.csv");
  EXPECT_TRUE(b.metadata.site->site_from_map.translation.isApprox(Eigen::Vector3d(10, -2, 0.5)));

  // A map that records none says so on the wire too (not a zero correction).
  mapstore::SaveMap(MakeSyntheticMap({}), dir.File("plain.db"));
  v1::MapInfo plain;
  proto::ToProto(mapstore::MapDirectory(dir.path()).Describe("plain"), &plain);
  EXPECT_FALSE(plain.has_disparity_correction());
  EXPECT_FALSE(proto::FromProto(plain, "plain").info->metadata.disparity_correction.has_value());
  EXPECT_FALSE(plain.has_rig_error());
  EXPECT_FALSE(proto::FromProto(plain, "plain").info->metadata.rig_error.has_value());
  EXPECT_FALSE(plain.has_stereo_baseline_m());
  EXPECT_FALSE(proto::FromProto(plain, "plain").info->metadata.stereo_baseline_m.has_value());
  EXPECT_FALSE(plain.has_gravity());
  EXPECT_FALSE(proto::FromProto(plain, "plain").info->metadata.gravity.has_value());
  EXPECT_FALSE(plain.has_site());
}

TEST(MapInfoConvertTest, ABrokenMapCarriesItsProblemAndAnEmptyBoxStaysEmpty) {
  v1::MapInfo broken;
  broken.set_name("old");
  broken.set_available(false);
  broken.set_problem("schema 1 is too old");
  const auto entry = proto::FromProto(broken, "old on server");
  EXPECT_FALSE(entry.info.has_value());
  EXPECT_EQ(entry.error, "schema 1 is too old");

  mapstore::MapDirectory::Entry empty;
  empty.name = "empty";
  empty.info = mapstore::MapInfo{};
  empty.info->camera = Camera(320, 240, 160, 160, 159.5, 119.5);
  v1::MapInfo wire;
  proto::ToProto(empty, &wire);
  EXPECT_FALSE(wire.details().has_point_extent());
  EXPECT_TRUE(proto::FromProto(wire, "x").info->point_extent.isEmpty());
}

TEST(MapInfoConvertTest, ALocalizabilityGridCrossesTheWireValueForValue) {
  LocalizabilityReport report;
  report.map = "hall";
  report.frame = "site";
  report.frame_how = "tied by pairs spots.csv";
  LocalizabilityGrid& grid = report.grid;
  grid.site_from_map = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())),
                               Eigen::Vector3d(1, 2, 3));
  grid.min_x_m = -2.5;
  grid.min_y_m = 4.0;
  grid.cell_m = 0.5;
  grid.cells_x = 3;
  grid.cells_y = 2;
  grid.headings = 4;
  grid.height_m = 1.2;
  grid.pitch_deg = 10.0;
  for (int i = 0; i < 24; ++i) {
    grid.estimates.push_back({static_cast<float>(i * 10), i % 5 ? 0.01f * i : INFINITY,
                              static_cast<float>(i), 0.1f * i, i % 2 == 0});
  }
  report.stats = {24, 12, 89, 0.25};
  v1::Localizability wire;
  proto::ToProto(report, &wire);
  const LocalizabilityReport back = proto::FromProto(wire);
  EXPECT_EQ(back.map, "hall");
  EXPECT_EQ(back.frame_how, report.frame_how);
  EXPECT_TRUE(back.grid.site_from_map.rotation.isApprox(grid.site_from_map.rotation));
  EXPECT_EQ(back.grid.cells_x, 3);
  EXPECT_EQ(back.grid.headings, 4);
  ASSERT_EQ(back.grid.estimates.size(), 24u);
  for (int i = 0; i < 24; ++i) {
    EXPECT_EQ(back.grid.estimates[i].expected_inliers, grid.estimates[i].expected_inliers);
    EXPECT_EQ(back.grid.estimates[i].position_sigma_m, grid.estimates[i].position_sigma_m);
    EXPECT_EQ(back.grid.estimates[i].good, grid.estimates[i].good);
  }
  EXPECT_EQ(back.stats.good_poses, 12);

  wire.mutable_good()->RemoveLast();
  try {
    proto::FromProto(wire);
    FAIL() << "a grid short of values was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("3 x 2 cells and 4 headings with 23 values"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace visloc
