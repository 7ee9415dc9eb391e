#include "proto/map_info_convert.h"

#include "core/util/check.h"
#include "proto/convert.h"
#include "proto/geometry_convert.h"

namespace visloc::proto {
namespace {

void BoxToProto(const Eigen::AlignedBox3d& box, v1::Box3* out) {
  out->set_min_x(box.min().x());
  out->set_min_y(box.min().y());
  out->set_min_z(box.min().z());
  out->set_max_x(box.max().x());
  out->set_max_y(box.max().y());
  out->set_max_z(box.max().z());
}

// An unset box is empty (Eigen's default box is).
Eigen::AlignedBox3d BoxFromProto(bool has_box, const v1::Box3& box) {
  if (!has_box) return Eigen::AlignedBox3d();
  return Eigen::AlignedBox3d(Eigen::Vector3d(box.min_x(), box.min_y(), box.min_z()),
                             Eigen::Vector3d(box.max_x(), box.max_y(), box.max_z()));
}

void DetailsToProto(const mapstore::MapInfo& info, v1::MapDetails* out) {
  ToProto(info.camera, out->mutable_camera());
  out->set_descriptor_type(ToString(info.features.descriptor_type));
  out->set_descriptor_dim(info.features.descriptor_dim);
  out->set_observations(info.observations);
  out->set_mean_reproj_error_px(info.mean_reproj_error_px);
  if (!info.point_extent.isEmpty()) BoxToProto(info.point_extent, out->mutable_point_extent());
  if (!info.keyframe_extent.isEmpty()) {
    BoxToProto(info.keyframe_extent, out->mutable_keyframe_extent());
  }
  out->set_kernel_learned(info.kernel_learned);
  out->set_default_k(info.kernel.default_k);
  out->set_default_probability_threshold(info.kernel.default_probability_threshold);
  out->set_vocabulary_words(info.vocabulary_words);
  out->set_memory_bytes(info.memory_bytes);
}

}  // namespace

void ToProto(const mapstore::MapDirectory::Entry& entry, v1::MapInfo* out) {
  out->set_name(entry.name);
  out->set_size_bytes(entry.file_bytes);
  out->set_available(entry.info.has_value());
  if (!entry.info) return;
  const mapstore::MapInfo& info = *entry.info;
  out->set_keyframes(static_cast<uint32_t>(info.keyframes));
  out->set_points(info.points);
  out->set_feature_kind(info.features.kind);
  out->set_schema_version(info.schema_version);
  out->set_builder(info.metadata.builder);
  out->set_source_dataset(info.metadata.source_dataset);
  out->set_created_unix_s(info.metadata.created_unix_s);
  out->set_lineage(info.metadata.lineage);
  if (info.metadata.disparity_correction) {
    ToProto(*info.metadata.disparity_correction, out->mutable_disparity_correction());
  }
  if (const auto& rig = info.metadata.rig_error) {
    out->mutable_rig_error()->set_floor_m(rig->floor_m);
    out->mutable_rig_error()->set_drift_fraction(rig->drift_fraction);
  }
  if (const auto& baseline_m = info.metadata.stereo_baseline_m) out->set_stereo_baseline_m(*baseline_m);
  if (const auto& gravity = info.metadata.gravity) {
    v1::MapGravity* wire = out->mutable_gravity();
    wire->set_up_x(gravity->up_in_map.x());
    wire->set_up_y(gravity->up_in_map.y());
    wire->set_up_z(gravity->up_in_map.z());
    wire->set_sigma_deg(gravity->sigma_deg);
    wire->set_source(GravitySourceName(gravity->source));
  }
  if (const auto& site = info.metadata.site) {
    v1::SiteAlignment* wire = out->mutable_site();
    ToProto(site->site_from_map, wire->mutable_site_from_map());
    wire->set_pairs(static_cast<uint32_t>(site->pairs));
    wire->set_rms_m(site->rms_m);
    wire->set_max_residual_m(site->max_residual_m);
    wire->set_reference(site->reference);
  }
  DetailsToProto(info, out->mutable_details());
}

mapstore::MapDirectory::Entry FromProto(const v1::MapInfo& wire, const std::string& path) {
  mapstore::MapDirectory::Entry entry;
  entry.name = wire.name();
  entry.path = path;
  entry.file_bytes = wire.size_bytes();
  if (!wire.available()) {
    entry.error = wire.problem();
    return entry;
  }
  mapstore::MapInfo info;
  info.path = path;
  info.file_bytes = wire.size_bytes();
  info.schema_version = static_cast<int>(wire.schema_version());
  info.metadata = {wire.name(), wire.created_unix_s(), wire.source_dataset(), wire.builder(),
                   wire.lineage()};
  if (wire.has_disparity_correction()) {
    info.metadata.disparity_correction = FromProto(wire.disparity_correction());
  }
  if (wire.has_rig_error()) {
    info.metadata.rig_error = RigError{wire.rig_error().floor_m(), wire.rig_error().drift_fraction()};
  }
  if (wire.has_stereo_baseline_m()) info.metadata.stereo_baseline_m = wire.stereo_baseline_m();
  if (wire.has_gravity()) {
    // A listing from a server: shown, never trusted for arithmetic, so an unknown source (a
    // newer server's) reads as the IMU's rather than failing the listing.
    const v1::MapGravity& gravity = wire.gravity();
    info.metadata.gravity = MapGravity{
        Eigen::Vector3d(gravity.up_x(), gravity.up_y(), gravity.up_z()), gravity.sigma_deg(),
        ParseGravitySource(gravity.source()).value_or(MapGravity::Source::kImu)};
  }
  if (wire.has_site()) {
    const v1::SiteAlignment& site = wire.site();
    info.metadata.site = SiteAlignment{FromProto(site.site_from_map(), "site_from_map"),
                                       static_cast<int>(site.pairs()), site.rms_m(),
                                       site.max_residual_m(), site.reference()};
  }
  info.features.kind = wire.feature_kind();
  info.keyframes = wire.keyframes();
  info.points = wire.points();
  const v1::MapDetails& details = wire.details();
  if (wire.has_details()) {  // A server from before MapDetails sends counts only.
    info.camera = FromProto(details.camera(), WireLimits{1 << 16, 1 << 16});
    info.features.descriptor_type = ParseDescriptorType(details.descriptor_type());
    info.features.descriptor_dim = static_cast<int>(details.descriptor_dim());
  }
  info.observations = details.observations();
  info.mean_reproj_error_px = details.mean_reproj_error_px();
  info.point_extent = BoxFromProto(details.has_point_extent(), details.point_extent());
  info.keyframe_extent = BoxFromProto(details.has_keyframe_extent(), details.keyframe_extent());
  info.kernel_learned = details.kernel_learned();
  info.kernel.default_k = static_cast<int>(details.default_k());
  info.kernel.default_probability_threshold = details.default_probability_threshold();
  info.vocabulary_words = details.vocabulary_words();
  info.memory_bytes = details.memory_bytes();
  entry.info = info;
  return entry;
}

}  // namespace visloc::proto

namespace visloc::proto {

void ToProto(const LocalizabilityReport& report, v1::Localizability* out) {
  const LocalizabilityGrid& grid = report.grid;
  out->set_map(report.map);
  out->set_frame(report.frame);
  out->set_frame_how(report.frame_how);
  ToProto(grid.site_from_map, out->mutable_site_from_map());
  out->set_min_x_m(grid.min_x_m);
  out->set_min_y_m(grid.min_y_m);
  out->set_cell_m(grid.cell_m);
  out->set_cells_x(static_cast<uint32_t>(grid.cells_x));
  out->set_cells_y(static_cast<uint32_t>(grid.cells_y));
  out->set_headings(static_cast<uint32_t>(grid.headings));
  out->set_height_m(grid.height_m);
  out->set_pitch_deg(grid.pitch_deg);
  const int poses = static_cast<int>(grid.estimates.size());
  out->mutable_expected_inliers()->Reserve(poses);
  out->mutable_position_sigma_m()->Reserve(poses);
  out->mutable_point_variance_ratio()->Reserve(poses);
  out->mutable_good()->Reserve(poses);
  out->mutable_visible_points()->Reserve(poses);
  for (const LocalizabilityEstimate& e : grid.estimates) {
    out->add_expected_inliers(e.expected_inliers);
    out->add_position_sigma_m(e.position_sigma_m);
    out->add_point_variance_ratio(e.point_variance_ratio);
    out->add_good(e.good);
    out->add_visible_points(e.visible_points);
  }
  out->set_good_poses(static_cast<uint32_t>(report.stats.good_poses));
  out->set_keyframes(static_cast<uint32_t>(report.stats.keyframes));
  out->set_seconds(report.stats.seconds);
}

LocalizabilityReport FromProto(const v1::Localizability& in) {
  LocalizabilityReport answer;
  answer.map = in.map();
  answer.frame = in.frame();
  answer.frame_how = in.frame_how();
  LocalizabilityGrid& grid = answer.grid;
  grid.site_from_map = FromProto(in.site_from_map(), "site_from_map");
  grid.min_x_m = in.min_x_m();
  grid.min_y_m = in.min_y_m();
  grid.cell_m = in.cell_m();
  grid.cells_x = static_cast<int>(in.cells_x());
  grid.cells_y = static_cast<int>(in.cells_y());
  grid.headings = static_cast<int>(in.headings());
  grid.height_m = in.height_m();
  grid.pitch_deg = in.pitch_deg();
  const size_t poses = static_cast<size_t>(in.cells_x()) * in.cells_y() * in.headings();
  for (const int size :
       {in.expected_inliers_size(), in.position_sigma_m_size(), in.point_variance_ratio_size(),
        in.good_size(), in.visible_points_size()}) {
    if (static_cast<size_t>(size) != poses) {
      throw InputError(StrCat("a localizability grid of ", in.cells_x(), " x ", in.cells_y(),
                              " cells and ", in.headings(), " headings with ", size,
                              " values in a field"));
    }
  }
  grid.estimates.resize(poses);
  for (size_t i = 0; i < poses; ++i) {
    LocalizabilityEstimate& e = grid.estimates[i];
    e.expected_inliers = in.expected_inliers(static_cast<int>(i));
    e.position_sigma_m = in.position_sigma_m(static_cast<int>(i));
    e.point_variance_ratio = in.point_variance_ratio(static_cast<int>(i));
    e.good = in.good(static_cast<int>(i));
    e.visible_points = in.visible_points(static_cast<int>(i));
  }
  answer.stats.poses = static_cast<int>(poses);
  answer.stats.good_poses = static_cast<int>(in.good_poses());
  answer.stats.keyframes = static_cast<int>(in.keyframes());
  answer.stats.seconds = in.seconds();
  return answer;
}

}  // namespace visloc::proto
