#pragma once
// Chessboard views for calibration, rendered through a rig of known parameters, so that a
// calibration can be checked against the truth: the board held at different distances, tilts,
// turns and places across both images (into the corners, where lens distortion shows), in an
// otherwise plain room.
//
// The folder gets left/NNN.png and right/NNN.png (the pairs, same names) and the rig's true
// calibration as EuRoC sensor files, truth/cam0/sensor.yaml and truth/cam1/sensor.yaml, with
// the left camera as the body (T_BS of cam0 is the identity), as `visloc calibrate` writes them.

#include <cstdint>
#include <string>

#include "sim/sequences.h"

namespace visloc::sim {

struct BoardViewOptions {
  int cols = 9;             // Inner corners per row.
  int rows = 6;             // Inner corners per column.
  double square_m = 0.04;   // Side of a square.
  int views = 25;
  uint64_t seed = 1;
  int supersample = 2;
  void Check() const;
};

struct BoardViewStats {
  int views = 0;
  int attempts = 0;  // Board poses drawn; those not whole in both images were redrawn.
};

BoardViewStats GenerateBoardViews(const RigOptions& rig, const BoardViewOptions& options,
                                  const std::string& dir);

}  // namespace visloc::sim
