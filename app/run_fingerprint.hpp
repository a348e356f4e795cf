// The fingerprint a resumable run writes beside its partial output: 16 hex digits of the 64-bit
// FNV-1a hash of everything that identifies the run (inputs, options), so `--resume` refuses the
// leftovers of another run. One builder for every run kind; the byte sequences hashed are part of
// the on-disk format (a partial output written by an earlier build must still resume), so the
// functions below must not change what they feed the hash.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "engine/calibration/calibration_grid.hpp"

namespace stampede::app {

class RunFingerprint {
 public:
  RunFingerprint& text(std::string_view bytes);      // the bytes as they are
  RunFingerprint& line(std::string_view bytes);      // the bytes, then '\n'
  RunFingerprint& number(double v);                  // "%.17g": distinct for distinct doubles
  RunFingerprint& integer(long long v);              // decimal
  // "key=value\n" for each pair, in order.
  RunFingerprint& options(const std::vector<std::pair<std::string, std::string>>& key_values);
  std::string hex() const;  // 16 lower-case hex digits

 private:
  std::uint64_t hash_ = 1469598103934665603ull;  // FNV-1a 64 offset basis
};

// `stampede fit`: the input, catalogue and weight paths (one line each, "" when absent), then the
// output header's key=value pairs (the effective options and the INPUT/CATALOG/WEIGHTS keys).
std::string fit_fingerprint(const std::string& input, const std::string& catalog, const std::string& weight,
                            const std::vector<std::pair<std::string, std::string>>& header);

// `stampede calibrate build`: the grid (radii and bulge fractions, each followed by ',', then
// |snr|e_max|e_steps|realisations|seed|) and the configuration's key=value pairs.
std::string calibration_build_fingerprint(const CalibrationGridOptions& grid,
                                          const std::vector<std::pair<std::string, std::string>>& config);

}  // namespace stampede::app
