#pragma once
// Loop correction through a pose graph (the essential graph of ORB-SLAM, Mur-Artal and Tardos,
// T-RO 2017; with a stereo rig the scale is observed, so SE(3) rather than Sim(3)).
//
// A closure that finds the drift large moves the current keyframe to where the old landmarks put
// it. Bundle adjustment of every keyframe would spread that over the run at a cost that grows
// with the map (9.5 s at 642 keyframes of the generated suite); the pose graph spreads it at a
// cost of milliseconds: its nodes are the keyframe poses, its edges the relative poses between
// keyframes as they were before the closure (consecutive keyframes, and those that share enough
// landmarks: what earlier closures joined stays joined), plus the loop's edge. Afterwards each
// landmark moves rigidly with the keyframe that first observed it; local bundle adjustment and the
// global one at the end refine the rest.
//
// Frames: every pose is the rectified left camera's cam_from_world (slam_state.h).

#include <vector>

#include "core/geometry/rigid3.h"
#include "mapping/slam_state.h"

namespace visloc::mapping {

struct PoseGraphOptions {
  // Keyframes that share at least this many landmarks are joined by an edge: the strong ones
  // only (an essential graph). On the generated building 30 gave about 60 edges a keyframe and
  // 2-3.5 s a correction across 2,400 keyframes; 100 took loop closure from 36 to 15 s with the
  // frames' error the same (median 2.5 and 2.1 cm, max 5.5 and 6.5 cm).
  int min_shared_landmarks = 100;
  // How firmly an edge holds its relative pose, per axis: the loop's drift goes where the edges
  // give most cheaply. The ratio weighs a degree against a centimetre.
  double translation_sigma_m = 0.01;
  double rotation_sigma_deg = 0.1;
  int max_iterations = 20;
  // A loop joins each keyframe of the current window to up to this many keyframes of the old
  // place (LoopEdges); 1: the closure's own edge only.
  int loop_edges_per_keyframe = 8;
  void Check() const;
};

// b_from_a: the pose of keyframe b relative to keyframe a (cam_b_from_cam_a).
struct PoseGraphEdge {
  int a = 0, b = 0;
  Rigid3d b_from_a;
};

// The graph's edges among keyframes [0, end) as their poses stand now: consecutive keyframes,
// and pairs sharing options.min_shared_landmarks landmarks; only those that reach a keyframe after
// `anchor`, as CorrectLoop holds the loop's old keyframe and every one before it (an edge between
// two held keyframes says nothing). Call before a closure merges tracks, so that the loop's own
// new links are not taken as edges of the drifted poses.
std::vector<PoseGraphEdge> CovisibilityEdges(const SlamState& state, int anchor, int end,
                                             const PoseGraphOptions& options);

struct PoseGraphSummary {
  int keyframes = 0;  // That the loop may move: those after its old keyframe.
  int edges = 0;
  int iterations = 0;
  double max_move_m = 0.0;  // The largest keyframe centre's move.
  double time_ms = 0.0;
};

// The edges a loop closed at keyframe closure.b onto keyframe closure.a adds to the graph, the
// closure's own first. The tracks the closure merges join the whole current window (its last
// `window` keyframes) to the old place, so each keyframe of the window, moved rigidly with the
// current one, is joined to the old keyframe and to the keyframes after it that share its
// landmarks (in `edges`: CovisibilityEdges anchored at closure.a), outside the window: up to
// options.loop_edges_per_keyframe of them. A revisited place's keyframes have dozens of
// covisibility edges each; a loop of one edge is outweighed by them and leaves the drift where it
// is (on the generated building, closure after closure moved keyframes 1 cm for a 5-8 cm
// correction).
std::vector<PoseGraphEdge> LoopEdges(const SlamState& state, const PoseGraphEdge& closure,
                                     int window, const std::vector<PoseGraphEdge>& edges,
                                     const PoseGraphOptions& options);

// Moves keyframes (old, current] so that they keep `edges` and the loop's edges as well as they
// can, where loop_edges.front() is the closure itself (a = old, b = current) and the others join
// keyframes of those two places (within [0, current]). The loop's old keyframe and every one
// before it are held: the drift the loop measures is the one accumulated since, and the problem's
// size is the loop's, not the run's. Landmarks move with the keyframe of their first observation.
PoseGraphSummary CorrectLoop(const std::vector<PoseGraphEdge>& edges,
                             const std::vector<PoseGraphEdge>& loop_edges,
                             const PoseGraphOptions& options, SlamState* state);

}  // namespace visloc::mapping
