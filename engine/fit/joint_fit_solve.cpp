// The joint fits' shared solve; see joint_fit_solve.hpp.
#include "engine/fit/joint_fit_solve.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stampede {

Renderer& CutoutScratch::select(Renderer& r, const Observation& e, bool surrogate) {
  r.set_psf(e.psf);
  r.set_frame(e.frame);  // the surrogate follows the renderer's PSF and frame
  Renderer* coarse = surrogate ? r.surrogate() : nullptr;
  const std::size_t n = static_cast<std::size_t>(e.box_size) * e.box_size;
  if (model_.size() < n) {  // grows to the largest box once, then never again
    model_.resize(n);
    zeros_.resize(n);
    for (auto& j : jacobian_) j.resize(n);
  }
  model_span_ = std::span<double>(model_.data(), n);
  for (std::size_t k = 0; k < jacobian_.size(); ++k) columns_[k] = jacobian_[k].data();
  return coarse ? *coarse : r;
}

bool CutoutScratch::sums(const kernels::LeastSquaresKernels& k, std::span<const double> data,
                         std::span<const double> weight, int ncol, CutoutSums* out) {
  out->chi2 = k.normal_equations(data, model_span_, weight, columns_.data(), ncol, out->alpha.data(), out->beta.data());
  out->signal = k.weighted_chi2(std::span<const double>(zeros_.data(), model_span_.size()), model_span_, weight);
  if (!std::isfinite(out->chi2) || !std::isfinite(out->signal)) return false;
  for (int a = 0; a < ncol; ++a) {
    if (!std::isfinite(out->beta[static_cast<std::size_t>(a)])) return false;
    for (int b = 0; b < ncol; ++b)
      if (!std::isfinite(out->alpha[static_cast<std::size_t>(a * ncol + b)])) return false;
  }
  return true;
}

void KernelCutouts::reset(std::span<const Observation> epochs, const FitUnits& units) {
  data_.resize(epochs.size());
  weight_.resize(epochs.size());
  if (scaled_data_.size() < epochs.size()) scaled_data_.resize(epochs.size()), scaled_weight_.resize(epochs.size());
  const double to_data = 1.0 / units.data, to_weight = 1.0 / units.weight;  // powers of two: exact
  for (std::size_t c = 0; c < epochs.size(); ++c) {
    const Observation& e = epochs[c];
    const double s = e.flux_scale;
    if (s == 1 && to_data == 1 && to_weight == 1) {
      data_[c] = e.pixels, weight_[c] = e.weight;
      continue;
    }
    std::vector<double>& d = scaled_data_[c];
    std::vector<double>& w = scaled_weight_[c];
    d.resize(e.pixels.size()), w.resize(e.weight.size());
    for (std::size_t i = 0; i < e.pixels.size(); ++i)
      d[i] = e.pixels[i] / s * to_data, w[i] = e.weight[i] * s * s * to_weight;
    data_[c] = d, weight_[c] = w;
  }
}

void JointCutouts::reset(std::span<const Observation> epochs) {
  epochs_ = epochs;
  pixels_ = 0;
  double sum = 0, max_abs = 0, max_weight = 0;
  for (const Observation& e : epochs) {
    // The largest |d| and w of a cutout; over s and s^2 they are the largest of its kernel data
    // (division and multiplication by a positive number keep the order).
    double cutout_abs = 0, cutout_weight = 0;
    for (std::size_t i = 0; i < e.weight.size(); ++i) {
      const double w = e.weight[i], d = e.pixels[i];
      pixels_ += w > 0;
      sum += w * d * d;
      if (w > 0 && std::isfinite(w) && std::isfinite(d)) {
        cutout_abs = std::max(cutout_abs, std::abs(d));
        cutout_weight = std::max(cutout_weight, w);
      }
    }
    const double s = std::abs(e.flux_scale);
    max_abs = std::max(max_abs, cutout_abs / s);
    max_weight = std::max(max_weight, cutout_weight * s * s);
  }
  units_ = FitUnits::for_data(max_abs, max_weight);
  data_.reset(epochs, units_);
  negligible_chi2_ = 1e-14 * sum / units_.chi2();
}

bool JointCutouts::chi2(std::size_t c, const ParamVector& p, double* chi2) {
  Renderer& r = select(c);
  if (r.render(p, scratch_.model()) != RenderStatus::kOk) return false;
  *chi2 = scratch_.chi2(kernels_, data_.data(c), data_.weight(c));
  return true;
}

bool JointCutouts::sums(std::size_t c, const ParamVector& p, std::span<const Param> free, CutoutSums* out) {
  Renderer& r = select(c);
  return r.render_with_jacobian(p, free, scratch_.model(), scratch_.columns(free.size())) == RenderStatus::kOk &&
         scratch_.sums(kernels_, data_.data(c), data_.weight(c), static_cast<int>(free.size()), out);
}

FitStatus check_cutouts(std::span<const Observation> epochs, const char* who) {
  for (const Observation& e : epochs) {
    if (!e.psf) return FitStatus::kPsfFailure;
    const std::size_t n = static_cast<std::size_t>(e.box_size) * e.box_size;
    if (e.box_size < 1 || e.pixels.size() != n || e.weight.size() != n)
      throw std::invalid_argument(std::string(who) + ": a cutout's pixels or weights are not box_size^2");
  }
  return FitStatus::kOk;
}

}  // namespace stampede
