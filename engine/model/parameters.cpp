// Parameter names, defaults and validation; see parameters.hpp.
#include "engine/model/parameters.hpp"

#include <limits>
#include <sstream>

namespace stampede {

std::string_view param_name(Param p) {
  switch (p) {
    case Param::kX0: return "x0";
    case Param::kY0: return "y0";
    case Param::kE1: return "e1";
    case Param::kE2: return "e2";
    case Param::kRadius: return "radius";
    case Param::kBulgeA: return "bulge_A";
    case Param::kDiscA: return "disc_A";
    case Param::kRadiusRatio: return "radius_ratio";
    case Param::kBulgeIndex: return "bulge_index";
    case Param::kDiscIndex: return "disc_index";
    case Param::kDeltaE: return "delta_e";
    case Param::kDeltaTheta: return "delta_theta";
  }
  return "?";
}

bool is_freeable(Param p) { return index(p) <= index(Param::kDiscA); }

std::array<ParamSpec, kNumParams> ParameterSet::defaults() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<ParamSpec, kNumParams> s;
  s[index(Param::kX0)] = {NAN, NAN, NAN, true};
  s[index(Param::kY0)] = {NAN, NAN, NAN, true};
  // e beyond the mirror folds back (appendix A), so the bounds only stop a runaway.
  s[index(Param::kE1)] = {NAN, -3.0, 3.0, true};
  s[index(Param::kE2)] = {NAN, -3.0, 3.0, true};
  s[index(Param::kRadius)] = {NAN, -100.0, 100.0, true};
  // Amplitudes are linear and unbounded: a component absent from the data must reach 0 freely.
  s[index(Param::kBulgeA)] = {NAN, -inf, inf, true};
  s[index(Param::kDiscA)] = {NAN, -inf, inf, true};
  s[index(Param::kRadiusRatio)] = {1.0, 0.01, 100.0, false};
  s[index(Param::kBulgeIndex)] = {4.0, 0.3, 8.0, false};
  s[index(Param::kDiscIndex)] = {1.0, 0.3, 8.0, false};
  s[index(Param::kDeltaE)] = {0.0, -0.95, 0.95, false};
  s[index(Param::kDeltaTheta)] = {0.0, -3.15, 3.15, false};
  return s;
}

ParamVector ParameterSet::default_values() {
  ParamVector p;
  const auto spec = defaults();
  for (int k = 0; k < kNumParams; ++k) p[k] = spec[k].start;
  return p;
}

int ParameterSet::num_free() const {
  int n = 0;
  for (const auto& s : spec) n += s.free ? 1 : 0;
  return n;
}

int ParameterSet::free_params(std::array<Param, kNumParams>* out) const {
  int n = 0;
  for (int k = 0; k < kNumParams; ++k)
    if (spec[k].free) (*out)[n++] = static_cast<Param>(k);
  return n;
}

bool ParameterSet::IsValid(std::string* why) const {
  for (int k = 0; k < kNumParams; ++k) {
    const Param p = static_cast<Param>(k);
    const ParamSpec& s = spec[k];
    std::ostringstream msg;
    if (s.free && !is_freeable(p)) {
      msg << "parameter '" << param_name(p) << "' cannot be free: no analytic derivative is implemented for it";
    } else if (!s.free && std::isnan(s.start) && index(p) > index(Param::kDiscA)) {
      msg << "parameter '" << param_name(p) << "' is fixed but has no value";
    } else if (!std::isnan(s.lower) && !std::isnan(s.upper) && !(s.lower < s.upper)) {
      msg << "parameter '" << param_name(p) << "' bounds [" << s.lower << ", " << s.upper
          << "] are empty: lower must be < upper";
    } else if (!std::isnan(s.start) && !std::isfinite(s.start)) {
      msg << "parameter '" << param_name(p) << "' start " << s.start << " must be finite";
    } else if (!std::isnan(s.start) && ((!std::isnan(s.lower) && s.start < s.lower) ||
                                         (!std::isnan(s.upper) && s.start > s.upper))) {
      msg << "parameter '" << param_name(p) << "' start " << s.start << " is outside its bounds [" << s.lower
          << ", " << s.upper << "]";
    }
    if (!msg.str().empty()) {
      if (why) *why = msg.str();
      return false;
    }
  }
  const double nb = spec[index(Param::kBulgeIndex)].start, nd = spec[index(Param::kDiscIndex)].start;
  for (double n : {nb, nd}) {
    if (!(n >= 0.3 && n <= 8.0)) {
      if (why) *why = "Sérsic index " + std::to_string(n) + " must be in [0.3, 8]";
      return false;
    }
  }
  if (num_free() == 0) {
    if (why) *why = "no free parameters";
    return false;
  }
  return true;
}

}  // namespace stampede
