#include "mapping/map_update.h"

#include <gtest/gtest.h>

#include "core/map/synthetic_map.h"
#include "core/util/check.h"

namespace visloc::mapping {
namespace {

// The place seen again by a session over the same keyframes (in a frame of its own), after
// every tenth point moved 0.5 m (a box carried away; its texture, so its descriptor, goes with
// it). The session's keyframes see every point in their image within 6 m, as a perfect
// detector would (the synthetic map's own visibility lists are not geometric).
Map ChangedSession(const Map& map, const Rigid3d& session_from_map, std::vector<bool>* moved) {
  Map session = map;
  session.metadata = {"session", 2, "/data/wed", "test", ""};
  moved->assign(map.points.size(), false);
  std::vector<Eigen::Vector3d> in_map(map.points.size());
  for (size_t p = 0; p < session.points.size(); ++p) {
    in_map[p] = map.points[p].position_in_map;
    if (p % 10 == 0) {
      in_map[p] += Eigen::Vector3d(0.5, 0.0, 0.0);
      (*moved)[p] = true;
    }
    session.points[p].position_in_map = session_from_map * in_map[p];
  }
  session.observations.clear();
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    const Rigid3d cam_from_map = map.keyframes[k].map_from_cam.Inverse();
    for (size_t p = 0; p < in_map.size(); ++p) {
      const Eigen::Vector3d in_cam = cam_from_map * in_map[p];
      Eigen::Vector2d pixel;
      if (in_cam.z() > 0.1 && in_cam.norm() < 6.0 && map.camera.Project(in_cam, &pixel) &&
          map.camera.IsInImage(pixel)) {
        session.observations.push_back({static_cast<uint32_t>(k), static_cast<uint32_t>(p),
                                        pixel.cast<float>()});
      }
    }
  }
  for (MapPoint& point : session.points) point.observation_count = 0;
  for (const Observation& o : session.observations) ++session.points[o.point].observation_count;
  for (Keyframe& k : session.keyframes) k.map_from_cam = session_from_map * k.map_from_cam;
  return session;
}

// MakeSyntheticMap's maps observe points outside the image, which no bundle adjustment can fit:
// these tests check the update's point check (map_adjustment_test checks the adjustment).
UpdateOptions RigidOnlyUpdate() {
  UpdateOptions options;
  options.merge.skip_adjustment = true;
  return options;
}

TEST(MapUpdateTest, RemovesWhatMovedKeepsTheRestAndAddsWhereItWent) {
  SyntheticMapOptions synthetic;
  synthetic.keyframes = 40;
  synthetic.points = 3000;
  Map map = MakeSyntheticMap(synthetic);
  map.metadata.name = "lab";
  const Rigid3d session_from_map(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())),
                                 Eigen::Vector3d(1.0, 0.0, -2.0));
  std::vector<bool> moved;
  const Map session = ChangedSession(map, session_from_map, &moved);
  UpdateStats stats;
  const Map updated = UpdateMap(map, session, RigidOnlyUpdate(), &stats);
  EXPECT_GT(stats.checked_points, 1000);
  // The kept points come first in the updated map, in their order: find which went.
  int removed_moved = 0, removed_unmoved = 0, moved_count = 0;
  size_t next = 0;
  for (size_t p = 0; p < map.points.size(); ++p) {
    moved_count += moved[p];
    // A kept point the session saw again is fused: it moves to the mean of the two estimates,
    // which here agree to rounding.
    if (next < updated.points.size() &&
        (updated.points[next].position_in_map - map.points[p].position_in_map).norm() < 1e-6) {
      ++next;
    } else {
      ++(moved[p] ? removed_moved : removed_unmoved);
    }
  }
  EXPECT_EQ(removed_moved + removed_unmoved, stats.removed_points);
  EXPECT_EQ(removed_unmoved, 0) << "points still in place were removed";
  EXPECT_GE(removed_moved, 0.5 * moved_count) << "moved points the session looked at stay";
  // The moved points come back at their new places, from the session.
  EXPECT_GE(stats.merge.added_points, stats.removed_points);
  EXPECT_TRUE(FindMapProblems(updated).empty());
  EXPECT_EQ(updated.metadata.lineage.rfind("update('lab' <- ", 0), 0u) << updated.metadata.lineage;
}

TEST(MapUpdateTest, ASessionPlacedByAGuessIsCheckedTheSameWay) {
  SyntheticMapOptions synthetic;
  synthetic.keyframes = 40;
  synthetic.points = 3000;
  const Map map = MakeSyntheticMap(synthetic);
  const Rigid3d session_from_map(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())),
      Eigen::Vector3d(1.0, 0.0, -2.0));
  std::vector<bool> moved;
  const Map session = ChangedSession(map, session_from_map, &moved);
  UpdateStats searched, placed;
  UpdateMap(map, session, RigidOnlyUpdate(), &searched);
  // The guess: where the session's localized images put it, a centimetre off.
  const Rigid3d guess = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0.0, 0.005)) *
                        session_from_map.Inverse();
  UpdateMap(map, session, RigidOnlyUpdate(), &placed, guess);
  EXPECT_TRUE(placed.merge.from_guess);
  EXPECT_EQ(placed.removed_points, searched.removed_points);
  EXPECT_EQ(placed.merge.fused_points, searched.merge.fused_points);
  EXPECT_TRUE(ApproxEqual(placed.merge.a_from_b, session_from_map.Inverse(), 1e-6, 1e-4));
}

TEST(MapUpdateTest, ASessionElsewhereIsRefused) {
  SyntheticMapOptions synthetic;
  synthetic.keyframes = 40;
  synthetic.points = 3000;
  const Map map = MakeSyntheticMap(synthetic);
  synthetic.seed = 9;
  const Map elsewhere = MakeSyntheticMap(synthetic);
  UpdateStats stats;
  EXPECT_THROW(UpdateMap(map, elsewhere, RigidOnlyUpdate(), &stats), InputError);
}

}  // namespace
}  // namespace visloc::mapping
