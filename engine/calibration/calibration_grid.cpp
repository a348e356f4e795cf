// Noise-bias calibration simulations; see calibration_grid.hpp.
#include "engine/calibration/calibration_grid.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "engine/model/parameters.hpp"
#include "engine/common/random_stream.hpp"

namespace stampede {
namespace {

constexpr std::uint64_t kNoisePurpose = 5;

std::string list(const std::vector<double>& v) {
  std::ostringstream s;
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? "," : "") << v[i];
  return s.str();
}

bool strictly_increasing(const std::vector<double>& v) {
  for (std::size_t i = 1; i < v.size(); ++i)
    if (!(v[i] > v[i - 1])) return false;
  return true;
}

}  // namespace

bool CalibrationGridOptions::IsValid(std::string* why) const {
  std::ostringstream m;
  std::string psf_why;
  const auto finite = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
  };
  if (radii.empty() || !finite(radii) || !strictly_increasing(radii) || radii.front() < 0.2 || radii.back() > 50)
    m << "radii " << list(radii) << ": need increasing radii in [0.2, 50] pixels";
  else if (bulge_fractions.empty() || !finite(bulge_fractions) || !strictly_increasing(bulge_fractions) ||
           bulge_fractions.front() < 0 || bulge_fractions.back() > 1)
    m << "bulge_fractions " << list(bulge_fractions) << ": need increasing fractions in [0, 1]";
  else if (!(e_max > 0 && e_max <= 0.9))
    m << "e_max " << e_max << ": must be in (0, 0.9]";
  else if (e_steps < 4 || e_steps > 201)
    m << "e_steps " << e_steps << ": must be in [4, 201] (a cubic needs four points)";
  else if (!(snr > 0 && std::isfinite(snr)))
    m << "snr " << snr << ": must be positive";
  else if (!(noise_sigma > 0 && std::isfinite(noise_sigma)))
    m << "noise_sigma " << noise_sigma << ": the calibration fits must be weighted (noise_sigma > 0)";
  else if (realisations < 2 || realisations > 1000000)
    m << "realisations " << realisations << ": must be in [2, 1000000] (noise pairs per point)";
  else if (stamp_size < 8 || stamp_size > 512)
    m << "stamp_size " << stamp_size << ": must be in [8, 512]";
  else if (!(bulge_radius_ratio > 0.01 && bulge_radius_ratio <= 100))
    m << "radius_ratio " << bulge_radius_ratio << ": must be in (0.01, 100]";
  else if (psf.kind == PsfKind::kImage)
    m << "psf_input: the calibration simulations draw analytic PSFs only (moffat, airy)";
  else if (!psf.IsValid(&psf_why))
    m << psf_why;
  if (m.str().empty()) return true;
  if (why) *why = m.str();
  return false;
}

CalibrationGrid::CalibrationGrid(const CalibrationGridOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument(why);
  for (double r : options_.radii)
    for (double f : options_.bulge_fractions)
      for (BiasAxis axis : {BiasAxis::kE1, BiasAxis::kE2})
        for (int i = 0; i < options_.e_steps; ++i) {
          CalibrationPoint p;
          p.index = static_cast<int>(points_.size());
          p.radius = r;
          p.bulge_fraction = f;
          p.axis = axis;
          p.e_true = -options_.e_max + 2 * options_.e_max * i / (options_.e_steps - 1);
          points_.push_back(p);
        }
  SimRenderer::Options ro;
  ro.max_half_light_radius = 1.1 * options_.radii.back() * std::max(1.0, options_.bulge_radius_ratio);
  ro.max_e = std::max(0.95, options_.e_max);
  renderer_ = std::make_unique<SimRenderer>(options_.psf, ro);
}

void CalibrationGrid::render(const CalibrationPoint& point, std::span<double> stamp,
                             SimWorkspace& workspace) const {
  const int s = options_.stamp_size;
  const double centre = 0.5 * (s - 1);
  std::vector<SimComponent> components;
  const double f = point.bulge_fraction;
  if (f > 0)
    components.push_back({4.0, f, point.radius * options_.bulge_radius_ratio, point.e1(), point.e2(), centre, centre});
  if (f < 1) components.push_back({1.0, 1 - f, point.radius, point.e1(), point.e2(), centre, centre});
  renderer_->render(components, s, stamp, workspace);
  double sum2 = 0;
  for (double v : stamp) sum2 += v * v;
  const double flux = options_.snr * options_.noise_sigma / std::sqrt(sum2);
  for (double& v : stamp) v *= flux;
}

void CalibrationGrid::add_noise(int point, int realisation, double sign, std::span<const double> stamp,
                                std::span<double> out) const {
  RandomStream noise({options_.seed, static_cast<std::uint64_t>(point), static_cast<std::uint64_t>(realisation),
                      kNoisePurpose});
  for (std::size_t i = 0; i < stamp.size(); ++i) out[i] = stamp[i] + sign * options_.noise_sigma * noise.normal();
}

CalibrationSource::CalibrationSource(const CalibrationGrid& grid)
    : grid_(grid), stamp_(static_cast<std::size_t>(grid.options().stamp_size) * grid.options().stamp_size) {}

bool CalibrationSource::fill(StampBatch& batch) {
  batch.begin(next_);
  const long long per_point = grid_.objects_per_point();
  while (batch.count < batch.capacity() && next_ < grid_.objects()) {
    const int point = static_cast<int>(next_ / per_point);
    const int within = static_cast<int>(next_ % per_point);
    if (point != drawn_point_) {
      grid_.render(grid_.points()[static_cast<std::size_t>(point)], stamp_, workspace_);
      drawn_point_ = point;
    }
    const int k = batch.count;
    std::span<double> pixels, weights;
    batch.observations.add_stamp(grid_.options().stamp_size, &pixels, &weights).weighted = false;
    grid_.add_noise(point, within / 2, within % 2 == 0 ? 1.0 : -1.0, stamp_, pixels);
    ObjectRecord& r = batch.records[static_cast<std::size_t>(k)];
    r = ObjectRecord{};
    r.id = next_;
    r.ix = point;
    r.iy = within;
    ++batch.count;
    ++next_;
  }
  return batch.count > 0;
}

PointBiasAccumulator::PointBiasAccumulator(const CalibrationGrid& grid,
                                           std::function<void(int, const PointBias&)> done)
    : grid_(grid), done_(std::move(done)) {}

void PointBiasAccumulator::add(std::span<const ObjectRecord> rows) {
  const long long per_point = grid_.objects_per_point();
  for (const ObjectRecord& r : rows) {
    if (next_object_ < 0) {
      if (r.id % per_point != 0) throw std::logic_error("PointBiasAccumulator: rows must start at a point boundary");
      next_object_ = r.id;
    }
    if (r.id != next_object_) throw std::logic_error("PointBiasAccumulator: rows out of order");
    ++next_object_;
    const int point = static_cast<int>(r.id / per_point);
    const long long within = r.id % per_point;
    const CalibrationPoint& p = grid_.points()[static_cast<std::size_t>(point)];
    const double e_fit[2] = {r.fit.params[index(Param::kE1)], r.fit.params[index(Param::kE2)]};
    const bool usable = usable_for_shear(r.fit.status, r.flags) && std::isfinite(e_fit[0]) && std::isfinite(e_fit[1]);
    if (within % 2 == 0) {
      plus_[0] = e_fit[0];
      plus_[1] = e_fit[1];
      plus_usable_ = usable;
    } else if (usable && plus_usable_) {
      const double truth[2] = {p.e1(), p.e2()};
      for (int c = 0; c < 2; ++c) {
        const double d = 0.5 * (plus_[c] + e_fit[c]) - truth[c];
        sum_[c] += d;
        sum2_[c] += d * d;
      }
      ++used_;
    } else {
      ++failed_;
    }
    if (within == per_point - 1) {
      PointBias b;
      b.pairs_used = used_;
      b.pairs_failed = failed_;
      for (int c = 0; c < 2; ++c) {
        if (used_ == 0) {
          b.bias[c] = b.error[c] = NAN;
          continue;
        }
        const double mean = sum_[c] / used_;
        b.bias[c] = mean;
        b.error[c] = used_ > 1 ? std::sqrt(std::max(0.0, sum2_[c] / used_ - mean * mean) / (used_ - 1)) : NAN;
      }
      done_(point, b);
      sum_[0] = sum_[1] = sum2_[0] = sum2_[1] = 0;
      used_ = failed_ = 0;
    }
  }
}

}  // namespace stampede
