// The run fingerprint builder; see run_fingerprint.hpp.
#include "app/run_fingerprint.hpp"

#include <cstdio>

#include "app/version.hpp"
#include "io/file_digest.hpp"
#include "io/fits_file.hpp"

namespace stampede::app {

RunFingerprint& RunFingerprint::text(std::string_view bytes) {
  for (unsigned char c : bytes) hash_ = (hash_ ^ c) * 1099511628211ull;  // FNV-1a 64 prime
  return *this;
}

RunFingerprint& RunFingerprint::line(std::string_view bytes) { return text(bytes).text("\n"); }

RunFingerprint& RunFingerprint::number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return text(buf);
}

RunFingerprint& RunFingerprint::integer(long long v) { return text(std::to_string(v)); }

RunFingerprint& RunFingerprint::options(const std::vector<std::pair<std::string, std::string>>& key_values) {
  for (const auto& [k, v] : key_values) text(k).text("=").line(v);
  return *this;
}

std::string RunFingerprint::hex() const {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash_));
  return hex;
}

std::string fit_fingerprint(const std::vector<FingerprintFile>& files,
                            const std::vector<std::pair<std::string, std::string>>& header,
                            std::vector<std::string>* digests) {
  std::string out = "stampede " + std::string(program_version()) + "\n";
  for (const FingerprintFile& f : files) {
    const std::string digest = io::digest_file(io::fits_root_name(f.path)).text();
    out += f.role + " " + f.path + ": " + digest + "\n";
    if (digests) digests->push_back(digest);
  }
  for (const auto& [k, v] : header) out += k + "=" + v + "\n";
  return out;
}

std::string calibration_build_fingerprint(const CalibrationGridOptions& grid,
                                          const std::vector<std::pair<std::string, std::string>>& config) {
  RunFingerprint f;
  f.text("stampede ").line(program_version());
  for (const auto* list : {&grid.radii, &grid.bulge_fractions})
    for (double v : *list) f.number(v).text(",");
  f.text("|").number(grid.snr).text("|").number(grid.e_max).text("|").integer(grid.e_steps).text("|");
  f.integer(grid.realisations).text("|").text(std::to_string(grid.seed)).text("|");
  return f.options(config).hex();
}

}  // namespace stampede::app
