// Deterministic result rows for the table writer and reader tests, shared so that both exercise
// the same hard cases.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "engine/pipeline/object_record.hpp"
#include "io/result_columns.hpp"

namespace stampede::testing {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

// Deterministic rows exercising every column: NaN where a fit produced nothing, -0, inf, values
// that need all 17 digits, ids beyond 2^53 (exact in K, not in double), flags with bit 31 set.
inline ObjectRecord make_record(long long i, io::PositionColumns positions) {
  ObjectRecord r;
  if (positions == io::PositionColumns::kGrid) {
    r.id = i;
    r.ix = static_cast<std::int32_t>(i % 17);
    r.iy = static_cast<std::int32_t>(i / 17);
  } else {
    r.id = (1LL << 53) + 1 + 3 * i;
    r.x_image = 1.0 + i / 3.0;
    r.y_image = 4096.25 - 0.1 * static_cast<double>(i);
  }
  r.fit.status = static_cast<FitStatus>(i % 7);
  r.fit.stop_reason = static_cast<StopReason>(i % 9);
  if (IsUsable(r.fit.status)) {
    const double t = static_cast<double>(i);
    r.fit.params[index(Param::kX0)] = 19.0 + 0.01 * std::sin(t);
    r.fit.params[index(Param::kY0)] = 19.0 - 0.01 * std::cos(t);
    r.fit.params[index(Param::kE1)] = i % 10 == 0 ? -0.0 : 0.3 * std::sin(0.7 * t);
    r.fit.params[index(Param::kE2)] = 0.3 * std::cos(0.7 * t);
    r.fit.params[index(Param::kRadius)] = 1.5 + 1.0 / (t + 3.0);
    r.fit.params[index(Param::kBulgeA)] = i % 4 == 0 ? 0.0 : 1e-3 * t;
    r.fit.params[index(Param::kDiscA)] = 0.1 / 7.0 + t;
    r.fit.e1_err = i % 8 == 0 ? kNaN : 1e-300 * t;  // kFlagNoErrors
    r.fit.e2_err = 2.5e-2 / (t + 1.0);
    r.fit.bulge_flux = 12.0 * t;
    r.fit.disc_flux = 1e10 / 3.0;
    r.fit.flux = r.fit.bulge_flux + r.fit.disc_flux;
    r.fit.snr = i % 13 == 0 ? kInf : 20.0 + t;
    r.fit.chi2 = 1521.0 + 1.0 / 3.0;
    r.fit.likelihood = -r.fit.chi2 / 2;
  }
  r.fit.iterations = static_cast<int>(i % 200);
  r.fit.evaluations = static_cast<int>((3 * i) % 500);
  r.flags = (i % 3 == 0 ? std::uint32_t{kFlagMaskedPixels} : 0u) |
            (i % 11 == 0 ? std::uint32_t{kFlagEdge} : 0u) | (i % 5 == 0 ? 1u << 31 : 0u);
  r.time_us = i % 6 == 0 ? kNaN : 1234.5678 + i / 7.0;
  r.psf_e1 = -0.01 * static_cast<double>(i % 5);
  r.psf_e2 = 0.02;
  r.psf_fwhm = 2.85;
  // Metacal values (written only by metacal tables): NaN where a sheared fit failed.
  const double t = static_cast<double>(i);
  r.metacal.r11 = 1.0 + 0.01 * std::sin(t), r.metacal.r12 = i % 9 == 0 ? kNaN : -1e-3 / (t + 1);
  r.metacal.r21 = 2e-3 * std::cos(t), r.metacal.r22 = 0.9 + 1.0 / 3.0 / (t + 1);
  for (int k = 0; k < 4; ++k) {
    r.metacal.e1[k] = 0.2 * std::sin(t + k), r.metacal.e2[k] = -0.1 * std::cos(t - k);
    r.metacal.snr[k] = i % 13 == 0 ? kInf : 15.0 + t + k, r.metacal.radius[k] = 1.25 + 1e-9 * k;
  }
  return r;
}

inline std::vector<ObjectRecord> make_records(long long n, io::PositionColumns positions) {
  std::vector<ObjectRecord> rows;
  for (long long i = 0; i < n; ++i) rows.push_back(make_record(i, positions));
  return rows;
}

}  // namespace stampede::testing
