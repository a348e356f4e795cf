// The five images of metacalibration (Huff & Mandelbaum 2017; Sheldon & Huff 2017): the
// deconvolved galaxy reconvolved unsheared, and sheared by +-step in each component.
#pragma once

#include <array>
#include <cmath>

namespace stampede {

enum class MetacalType : int { kNoshear = 0, k1p, k1m, k2p, k2m };
inline constexpr int kNumMetacalTypes = 5;
inline constexpr std::array<MetacalType, kNumMetacalTypes> kMetacalTypes = {
    MetacalType::kNoshear, MetacalType::k1p, MetacalType::k1m, MetacalType::k2p, MetacalType::k2m};

// "noshear", "1p", "1m", "2p", "2m": the metacal papers' names, and the output columns' suffixes.
inline const char* metacal_type_name(MetacalType t) {
  static constexpr const char* kNames[] = {"noshear", "1p", "1m", "2p", "2m"};
  return kNames[static_cast<int>(t)];
}

// The reduced shear (g1, g2) a type applies with step `step`.
inline std::array<double, 2> metacal_shear(MetacalType t, double step) {
  switch (t) {
    case MetacalType::k1p: return {step, 0.0};
    case MetacalType::k1m: return {-step, 0.0};
    case MetacalType::k2p: return {0.0, step};
    case MetacalType::k2m: return {0.0, -step};
    case MetacalType::kNoshear: break;
  }
  return {0.0, 0.0};
}

// The unit-determinant matrix of reduced shear g: a galaxy G sheared by g is G(A^-1 x) (GalSim's
// convention: g1 > 0 stretches along x). Row-major {a00, a01, a10, a11}.
inline std::array<double, 4> shear_matrix(double g1, double g2) {
  const double s = 1.0 / std::sqrt(1.0 - g1 * g1 - g2 * g2);
  return {(1 + g1) * s, g2 * s, g2 * s, (1 - g1) * s};
}
inline std::array<double, 4> inverse_shear_matrix(double g1, double g2) { return shear_matrix(-g1, -g2); }

}  // namespace stampede
