// The noise-bias calibration file written by `stampede calibrate build` and read by `apply`.
//
// Layout (FITS):
//   primary  no data; the grid and the simulations: CALIBVER, SNRREF, NOISESIG, NREAL (noise pairs
//            per point), ESTEPS, EMAX, STAMPSZ, RRATIO (bulge / disc radius), SEED, RADII and
//            BFRACS (comma lists), the PSF (io/psf_keys.hpp); the fit configuration of the calibration run as
//            CFG0001.. = 'key = value', in the order of `stampede fit --help-config`
//   POINTS   one row per grid point: point radius bulge_fraction axis (0: e along e1, 1: along
//            e2) e_true bias1 bias1_err bias2 bias2_err pairs_used pairs_failed
//   CURVES   one row per (radius, bulge_fraction, axis, component): a0 a1 a2 a3 (the cubic
//            e_fit - e_true = sum a_k e_true^k), their errors a0_err .. a3_err, chi2, points
#pragma once

#include <string>

#include "engine/calibration/noise_bias.hpp"

namespace stampede::io {

// Writes PATH (replacing it when overwrite). Throws FitsError naming the file.
void write_calibration_table(const std::string& path, const CalibrationTable& table, bool overwrite);

// Reads a file written by write_calibration_table; throws FitsError naming the file, HDU or key
// when it is not one.
CalibrationTable read_calibration_table(const std::string& path);

}  // namespace stampede::io
