#pragma once
// Deterministic random numbers. The distributions are implemented here rather than taken from
// <random>, whose std::normal_distribution output differs between standard libraries: a
// synthetic sequence generated from a seed must be the same on every machine.

#include <cstdint>
#include <random>

namespace visloc {

class Rng {
 public:
  explicit Rng(uint64_t seed) : engine_(seed) {}

  // Uniform in [0, 1).
  double Uniform01() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double Uniform(double low, double high) { return low + (high - low) * Uniform01(); }
  // Uniform integer in [low, high].
  int UniformInt(int low, int high) {
    return low + static_cast<int>(Uniform01() * (static_cast<double>(high) - low + 1.0));
  }
  // Standard normal by the Box-Muller transform.
  double Normal(double mean = 0.0, double sigma = 1.0);
  uint64_t NextU64() { return engine_(); }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace visloc
