// The galaxy model's parameters as data: which are free, their start values and bounds.
//
// All twelve parameters of the im3shape bulge+disc model (paper table 2) are listed; the default
// set frees the seven of the paper's fits. Freeing a fixed one is a change of data here plus its
// derivative image in the renderer, not a redesign: `is_freeable` says which have one today.
#pragma once

#include <array>
#include <cmath>
#include <span>
#include <string>
#include <string_view>

namespace stampede {

enum class Param : int {
  kX0 = 0,        // centroid x, data pixels (0-based, pixel centres at integers)
  kY0,            // centroid y
  kE1,            // ellipticity (a-b)/(a+b), +x elongation; mirrored radially about |e| = 0.95
  kE2,            // ellipticity along y = x
  kRadius,        // disc half-light radius r_d (circularised), pixels; softened near 0
  kBulgeA,        // bulge central intensity A_b, flux / pixel^2
  kDiscA,         // disc central intensity A_d, flux / pixel^2
  kRadiusRatio,   // R_r = bulge / disc half-light radius
  kBulgeIndex,    // n_b, Sérsic index of the bulge
  kDiscIndex,     // n_d, Sérsic index of the disc
  kDeltaE,        // |e_bulge| - |e_disc|
  kDeltaTheta,    // bulge position angle - disc position angle, radians
};
inline constexpr int kNumParams = 12;
using ParamVector = std::array<double, kNumParams>;

inline constexpr int index(Param p) { return static_cast<int>(p); }
std::string_view param_name(Param p);
// True when the renderer has an analytic derivative image for p.
bool is_freeable(Param p);

struct ParamSpec {
  double start = NAN;   // NaN: taken from the image moments (x0, y0, e1, e2, radius, amplitudes)
  double lower = NAN;   // NaN: a default derived from the stamp (x0, y0: inside the stamp)
  double upper = NAN;
  bool free = false;
};

struct ParameterSet {
  std::array<ParamSpec, kNumParams> spec = defaults();

  static std::array<ParamSpec, kNumParams> defaults();
  // The default start of every parameter (NaN where the moments decide).
  static ParamVector default_values();
  ParamSpec& operator[](Param p) { return spec[index(p)]; }
  const ParamSpec& operator[](Param p) const { return spec[index(p)]; }

  // Number of free parameters and their ids in Param order.
  int num_free() const;
  int free_params(std::array<Param, kNumParams>* out) const;

  // Message names the parameter, its value and the broken constraint.
  bool IsValid(std::string* why) const;
};

}  // namespace stampede
