// The fingerprint a resumable run writes beside its partial output, so that `--resume` refuses the
// leftovers of another run: another program version, configuration, input path or input content.
//   fit: lines of text (the catalogue writer's refusal quotes the first line that differs), each
//        input file identified by its size and the XXH64 of its bytes (io/file_digest.hpp);
//   calibrate build: 16 hex digits of the 64-bit FNV-1a hash of its grid and configuration (it has
//        no input files).
// The bytes are part of the on-disk format: changing what is fed in makes every partial output
// written by an earlier build unresumable, so do it only to identify runs better (and say so).
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

// A file a fit reads: its role ("input", "catalog", "weight", "psf_image") and its path as given
// (CFITSIO syntax such as "in.fits[1]" allowed: the file on disk is digested).
struct FingerprintFile {
  std::string role;
  std::string path;
  // The header key that records this file's identity ("N bytes, xxh64 H"); "" = none.
  std::string digest_key = "";
};

// `stampede fit`: "stampede VERSION\n"; then per file, in the order given, "ROLE PATH: N bytes,
// xxh64 H\n" (io::FileDigest::text()); then "key=value\n" per pair of the output header (the
// effective options and the INPUT/CATALOG/WEIGHTS keys). Reads every file once; throws io::FileError
// naming a file it cannot read. With `digests`, each file's "N bytes, xxh64 H" too, in order.
std::string fit_fingerprint(const std::vector<FingerprintFile>& files,
                            const std::vector<std::pair<std::string, std::string>>& header,
                            std::vector<std::string>* digests = nullptr);

// `stampede calibrate build`: the program version line "stampede VERSION\n", the grid (radii and
// bulge fractions, each followed by ',', then |snr|e_max|e_steps|realisations|seed|) and the
// configuration's key=value pairs.
std::string calibration_build_fingerprint(const CalibrationGridOptions& grid,
                                          const std::vector<std::pair<std::string, std::string>>& config);

}  // namespace stampede::app
