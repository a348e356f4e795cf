// The simulations of the noise-bias calibration (im3shape section 5.3): a grid of galaxy
// properties -- disc half-light radius r_d, bulge flux fraction F, and a true ellipticity e along
// the e1 or the e2 axis -- each drawn noise-free once at the reference S/N and then fitted under
// many noise realisations.
//
// Realisations come in pairs (n, -n): the pair mean of e_fit - e_true cancels the odd orders of
// the noise and keeps the bias (second order) with a far smaller scatter than single draws, so a
// point's bias is known to the same precision from ~10x fewer fits. Every random number comes from
// a stream keyed by (seed, point, realisation): the objects are identical for any thread count and
// for a run resumed at any object.
//
// Object k of the run is point k / (2R), realisation (k % 2R) / 2, noise sign + for even k
// (R = realisations). Galaxies are co-elliptical, co-centred bulge + disc at the stamp's centre,
// the bulge's radius r_d times the fitter's fixed radius ratio, drawn by SimRenderer.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/sim/sim_renderer.hpp"
#include "engine/pipeline/object_record.hpp"
#include "engine/model/psf_model.hpp"
#include "engine/pipeline/stamp_batch.hpp"

namespace stampede {

struct CalibrationGridOptions {
  std::vector<double> radii = {1.0, 2.5, 5.0};          // r_d, pixels
  std::vector<double> bulge_fractions = {0.0, 0.5, 1.0};  // F = bulge flux / total flux
  double e_max = 0.8;   // e_true runs over [-e_max, e_max] ...
  int e_steps = 17;     // ... in this many equal steps, along e1 and along e2
  double snr = 20.0;    // reference S/N: sqrt(sum I^2) / noise_sigma of the noise-free stamp
  double noise_sigma = 1.0;
  int realisations = 16;  // noise pairs (n, -n) per grid point
  int stamp_size = 39;
  double bulge_radius_ratio = 1.0;  // bulge / disc half-light radius: the fitter's fixed ratio
  PsfModel psf;                     // Moffat or Airy (the simulator draws analytic PSFs)
  std::uint64_t seed = 11;
  // Message names the option as on the command line (--radii, --snr, ...), its value and the rule.
  bool IsValid(std::string* why) const;
};

enum class BiasAxis { kE1 = 0, kE2 = 1 };

struct CalibrationPoint {
  int index = 0;
  double radius = 0, bulge_fraction = 0;
  BiasAxis axis = BiasAxis::kE1;
  double e_true = 0;  // along `axis`; the other component is 0
  double e1() const { return axis == BiasAxis::kE1 ? e_true : 0.0; }
  double e2() const { return axis == BiasAxis::kE2 ? e_true : 0.0; }
};

class CalibrationGrid {
 public:
  // Validates (throws std::invalid_argument with IsValid's message) and builds the renderer.
  explicit CalibrationGrid(const CalibrationGridOptions& options);
  const CalibrationGridOptions& options() const { return options_; }
  // Ordered by radius, then bulge fraction, then axis, then e_true.
  const std::vector<CalibrationPoint>& points() const { return points_; }
  long long objects_per_point() const { return 2LL * options_.realisations; }
  long long objects() const { return objects_per_point() * static_cast<long long>(points_.size()); }
  // The noise-free stamp of a point, scaled to the reference S/N.
  void render(const CalibrationPoint& point, std::span<double> stamp, SimWorkspace& workspace) const;
  // stamp + sign * noise of (point, realisation), into out.
  void add_noise(int point, int realisation, double sign, std::span<const double> stamp, std::span<double> out) const;

 private:
  CalibrationGridOptions options_;
  std::vector<CalibrationPoint> points_;
  std::unique_ptr<SimRenderer> renderer_;
};

// The engine's input: the objects of a grid in order, each point drawn once when first needed.
class CalibrationSource final : public StampSource {
 public:
  explicit CalibrationSource(const CalibrationGrid& grid);
  long long total_objects() const override { return grid_.objects(); }
  void skip_to(long long index) override { next_ = index; }
  bool fill(StampBatch& batch) override;

 private:
  const CalibrationGrid& grid_;
  long long next_ = 0;
  int drawn_point_ = -1;
  std::vector<double> stamp_;
  SimWorkspace workspace_;
};

// The measured bias of one grid point: mean over usable noise pairs of
// (e_fit(+n) + e_fit(-n)) / 2 - e_true per component, with its standard error.
struct PointBias {
  double bias[2] = {0, 0};
  double error[2] = {0, 0};
  int pairs_used = 0;
  int pairs_failed = 0;  // a member not usable for shear (status or flags, as `stampede metrics`)
};

// Reduces the fitted rows of a run, in object order, to one PointBias per point; calls `done`
// with (point index, bias) as each point's last object arrives.
class PointBiasAccumulator {
 public:
  PointBiasAccumulator(const CalibrationGrid& grid, std::function<void(int, const PointBias&)> done);
  // Rows must arrive in object order, starting at a point boundary.
  void add(std::span<const ObjectRecord> rows);

 private:
  const CalibrationGrid& grid_;
  std::function<void(int, const PointBias&)> done_;
  long long next_object_ = -1;
  double plus_[2] = {0, 0};
  bool plus_usable_ = false;
  double sum_[2] = {0, 0}, sum2_[2] = {0, 0};
  int used_ = 0, failed_ = 0;
};

}  // namespace stampede
