#include "core/util/random.h"

#include <cmath>

namespace visloc {

double Rng::Normal(double mean, double sigma) {
  if (has_spare_) {
    has_spare_ = false;
    return mean + sigma * spare_;
  }
  double u1 = Uniform01();
  while (u1 <= 1e-300) u1 = Uniform01();
  const double u2 = Uniform01();
  const double radius = std::sqrt(-2.0 * std::log(u1));
  spare_ = radius * std::sin(2.0 * M_PI * u2);
  has_spare_ = true;
  return mean + sigma * radius * std::cos(2.0 * M_PI * u2);
}

}  // namespace visloc
