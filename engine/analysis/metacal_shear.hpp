// A set's shear from metacalibration rows (Sheldon & Huff 2017, section 4): g = (<R> + R_S)^-1 <e>,
// with <e> and <R> over the selected objects and the selection response
//   R_S,ij = (<e_i>_{S(+j)} - <e_i>_{S(-j)}) / (2 step),
// where S(+-j) is the same selection made on the quantities measured on the +-step_j images.
// Ring pairs are averaged first (a pair enters a selection only if both members pass), and errors
// come from a bootstrap over pairs, each resample repeating the whole estimate.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "engine/analysis/shear_metrics.hpp"
#include "engine/analysis/unit_shear_estimator.hpp"

namespace stampede {

struct MetacalRows {
  std::span<const double> e1, e2;                // the noshear fit's
  std::array<std::span<const double>, 4> r;      // R11 R12 R21 R22
  // Per object, bit 0: passes the selection on its noshear quantities; bits 1..4: passes it on
  // the 1p 1m 2p 2m images' quantities.
  std::span<const std::uint8_t> selected;
  std::span<const long long> pair;               // ring-pair labels (-1 or empty: none)
  double step = 0.01;
};

// The five selections of MetacalRows::selected, by bit: "noshear", "1p", "1m", "2p", "2m".
inline constexpr const char* kMetacalSelectionNames[5] = {"noshear", "1p", "1m", "2p", "2m"};

struct MetacalSetShear {
  SetShear shear;                 // g1, g2 calibrated, with bootstrap errors
  std::array<double, 4> r{};      // <R> (R11 R12 R21 R22)
  std::array<double, 4> r_sel{};  // R_S
  double g1_raw = 0, g2_raw = 0;  // <e>, uncalibrated
  // Units (ring pairs, lone objects) passing each selection (kMetacalSelectionNames). One that is
  // 0 leaves <e> over it undefined: g, <R>, R_S and <e> are then NaN (empty_selection() says which).
  std::array<long long, 5> selected_units{};
  // The first selection no unit passes (its index into kMetacalSelectionNames), or -1.
  int empty_selection() const {
    for (int s = 0; s < 5; ++s)
      if (selected_units[s] == 0) return s;
    return -1;
  }
};

MetacalSetShear estimate_metacal_set_shear(const MetacalRows& rows, double g1_true, double g2_true, int bootstrap,
                                           std::uint64_t seed);

// The same estimate over resampled units, for pairing with another set (shear_pairs.hpp). The
// units copy what they need from the columns.
std::unique_ptr<UnitShearEstimator> make_metacal_units(const MetacalRows& rows);

}  // namespace stampede
