#pragma once
// `visloc map localizability`'s picture: the site from above (x right, y up), each grid cell a
// small wheel of its headings, each wedge coloured by the inliers a camera looking that way can
// expect (red none -> yellow -> green plenty; white: nothing in view), under the map's points
// (grey) and the keyframes' path (blue), with a metric grid, the site's axes and a legend.

#include <string>

#include "core/localization/localizability.h"
#include "core/map/localization_map.h"

namespace visloc::cli {

struct LocalizabilityPlotInput {
  const LocalizabilityGrid* grid = nullptr;
  const LocalizationMap* map = nullptr;  // None: the grid alone (a server's map).
  double good_inliers = 30.0;            // Marked on the colour bar.
  std::string title;
};

// Writes a PNG. Throws InputError when it cannot be written.
void WriteLocalizabilityPng(const LocalizabilityPlotInput& input, const std::string& path);

}  // namespace visloc::cli
