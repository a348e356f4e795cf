// The exact Fourier-space fitting renderer; see exact_renderer.hpp.
#include "engine/render/exact_renderer.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <functional>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "engine/common/parallel_indices.hpp"
#include "kernels/ellipse.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/math/sinc.hpp"
#include "kernels/psf_profile.hpp"
#include "kernels/sersic.hpp"

namespace stampede {
namespace {

constexpr double kPi = std::numbers::pi;

using kernels::sinc;

// The PSF's transform (PSF(0) = 1) as a function of (kx, ky), and the |k| beyond which it stays
// at most `tolerance`.
struct PsfTransform {
  std::function<double(double, double)> at;
  double k_bound = 0;
};

PsfTransform psf_transform(const PsfModel& psf, double tolerance) {
  PsfTransform out;
  if (psf.kind == PsfKind::kMoffat) {
    const kernels::MoffatProfile& m = psf.moffat;
    const double alpha = kernels::moffat_alpha(m.fwhm, m.beta);
    const double t = m.truncation > 0 ? m.truncation / alpha : 0.0;
    // |S k| for the sheared profile: S^2 is the real-space form of the opposite shear at r = 1.
    const kernels::EllipseQuadratic s2 = kernels::ellipse_quadratic(-m.e1, -m.e2, 1.0);
    const double e = std::hypot(m.e1, m.e2), stretch = std::sqrt((1 + e) / (1 - e));
    // Largest x = k alpha with |transform| above the tolerance, scanned outwards (a truncated
    // Moffat's transform rings, so it is capped as in the simulator: five pixel-frequency aliases).
    const double x_cap = 10 * kPi * alpha;
    double x_limit = 1.0;
    for (double x = 0.25; x <= x_cap; x += 0.25)
      if (std::abs(kernels::moffat_fourier(m.beta, t, x)) > tolerance) x_limit = x + 0.25;
    x_limit = std::min(x_limit, x_cap);
    out.k_bound = x_limit / alpha * stretch;
    if (t == 0) {
      out.at = [=](double kx, double ky) {
        const double x = std::sqrt(std::max(0.0, s2(kx, ky))) * alpha;
        return x > x_limit ? 0.0 : kernels::moffat_fourier(m.beta, 0.0, x);
      };
    } else {
      // The truncated transform is a quadrature: tabulated as in the simulator (400 nodes per
      // decade keep >= 10 nodes per period of its ringing).
      auto table = std::make_shared<kernels::LogTable>([&](double x) { return kernels::moffat_fourier(m.beta, t, x); },
                                                       kernels::LogGrid::covering(1e-4, x_limit, 400));
      out.at = [=](double kx, double ky) {
        const double x = std::sqrt(std::max(0.0, s2(kx, ky))) * alpha;
        return x > table->q_max() ? 0.0 : (*table)(x);
      };
    }
    return out;
  }
  if (psf.kind == PsfKind::kAiry && psf.airy.obscuration == 0.0) {
    const double l = psf.airy.lambda_over_d;
    out.k_bound = 2 * kPi / l;  // the pupil's cut-off: exactly 0 beyond
    out.at = [=](double kx, double ky) { return kernels::airy_fourier(std::hypot(kx, ky) * l / (2 * kPi)); };
    return out;
  }
  throw std::invalid_argument(
      "the exact renderer's term list needs an analytic PSF transform (Moffat, unobscured Airy); image and "
      "obscured Airy PSFs are not supported yet");
}

// Signed frequency index of half-spectrum row jy (FFTW order).
int signed_row(int jy, int n) { return jy <= n / 2 ? jy : jy - n; }

}  // namespace

bool ExactRenderOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(psf_tolerance > 0 && psf_tolerance < 1e-2))
    msg << "exact_psf_tolerance = " << psf_tolerance << ": must be in (0, 1e-2)";
  else if (period < 0 || period > 4096)
    msg << "exact_period = " << period << ": must be 0 (the rule) or a grid size up to 4096 pixels";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

int exact_period(int stamp_size) { return kernels::fft_friendly_size(4 * stamp_size); }

std::shared_ptr<const kernels::KSpaceTerms> build_kspace_terms(const PsfModel& psf, int n, double tolerance) {
  std::string why;
  if (!psf.IsValid(&why)) throw std::invalid_argument("exact renderer PSF: " + why);
  if (n < 8) throw std::invalid_argument("exact renderer: period below 8 pixels");
  const PsfTransform p = psf_transform(psf, tolerance);
  auto terms = std::make_shared<kernels::KSpaceTerms>();
  const int half = n / 2 + 1;
  const int stride = (half + kernels::kKBlock - 1) / kernels::kKBlock * kernels::kKBlock;
  const int per_row = stride / kernels::kKBlock;
  const double dk = 2 * kPi / n;
  // Aliases out to where the PSF has fallen below the tolerance (sinc <= 1 only lowers it).
  const int m_max = static_cast<int>(std::ceil(p.k_bound / (2 * kPi) + 0.5));
  const int aliases = 2 * m_max + 1;
  terms->n = n;
  terms->row_stride = stride;
  terms->kx_values.resize(static_cast<std::size_t>(aliases) * stride);
  terms->ky_values.resize(static_cast<std::size_t>(aliases) * n);
  for (int a = 0; a < aliases; ++a) {
    for (int jx = 0; jx < stride; ++jx) terms->kx_values[static_cast<std::size_t>(a) * stride + jx] = 2 * kPi * (a - m_max) + dk * jx;
    for (int jy = 0; jy < n; ++jy)
      terms->ky_values[static_cast<std::size_t>(a) * n + jy] = 2 * kPi * (a - m_max) + dk * signed_row(jy, n);
  }
  const double norm = 1.0 / (static_cast<double>(n) * n);  // FFTW's unnormalised inverse
  terms->block_begin.reserve(static_cast<std::size_t>(n) * per_row + 1);
  for (int jy = 0; jy < n; ++jy)
    for (int b = 0; b < per_row; ++b) {
      terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
      for (int ay = 0; ay < aliases; ++ay) {
        const int iy = ay * n + jy;
        const double ky = terms->ky_values[static_cast<std::size_t>(iy)];
        if (std::abs(ky) > p.k_bound) continue;
        for (int ax = 0; ax < aliases; ++ax) {
          const int ix = ax * stride + b * kernels::kKBlock;
          std::array<double, kernels::kKBlock> v{};
          double largest = 0;
          for (int l = 0; l < kernels::kKBlock; ++l) {
            const int jx = b * kernels::kKBlock + l;
            const double kx = terms->kx_values[static_cast<std::size_t>(ix + l)];
            if (jx >= half || std::hypot(kx, ky) > p.k_bound) continue;  // padding column, or beyond the PSF
            v[l] = p.at(kx, ky) * sinc(0.5 * kx) * sinc(0.5 * ky);
            largest = std::max(largest, std::abs(v[l]));
          }
          if (!(largest > tolerance)) continue;
          terms->entry_ix.push_back(ix);
          terms->entry_iy.push_back(iy);
          for (double x : v) {
            terms->ppi_re.push_back(x * norm);
            terms->ppi_im.push_back(0.0);  // centrosymmetric analytic PSFs have real transforms
          }
        }
      }
    }
  terms->block_begin.push_back(static_cast<std::int32_t>(terms->entry_ix.size()));
  return terms;
}

std::shared_ptr<const kernels::SersicKTable> build_sersic_k_table(double n, double q_max) {
  // 40 nodes per decade from q = 1e-4: interpolation error ~1e-10 of F(0) (as the simulator's).
  const kernels::LogGrid grid = kernels::LogGrid::covering(1e-4, q_max, 40);
  std::vector<double> values(static_cast<std::size_t>(grid.count));
  parallel_indices(
      grid.count, 1, [] { return 0; },
      [&](int, long long i) {
        const double q = grid.node(static_cast<int>(i));
        values[static_cast<std::size_t>(i)] = n == 1.0 ? kernels::exponential_fourier(q) : kernels::sersic_fourier(n, q);
      });
  return std::make_shared<const kernels::SersicKTable>(grid, values);
}

std::shared_ptr<const kernels::SersicKTable> de_vaucouleurs_k_table() {
  // q = k r_e up to 2,000: k below ~10 rad/pixel where the PSF terms live, r_e up to ~30 pixels
  // at |e| = 0.95 (stretch 6.2). Beyond, the power law through the last two nodes (slope -1.96):
  // measured against the quadrature, 0.5 % of F (3e-8 of F(0)) at q = 3,000, 4 % (6e-8) at 6,000.
  static const std::shared_ptr<const kernels::SersicKTable> table = build_sersic_k_table(4.0, 2000.0);
  return table;
}

ExactRenderer::ExactRenderer(const RenderOptions& render, const ModelOptions& model, const ExactRenderOptions& options,
                             std::shared_ptr<const kernels::KSpaceTerms> terms,
                             std::shared_ptr<const kernels::SersicKTable> bulge_table, double bulge_index)
    : stamp_size_(render.stamp_size),
      n_(terms ? terms->n : 0),
      model_(model, 1.0 / render.upsampling),
      terms_(std::move(terms)),
      bulge_table_(std::move(bulge_table)),
      bulge_index_(bulge_index),
      kernels_(&kernels::kspace_kernels(render.simd)) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("ExactRenderer: " + why);
  if (!terms_) throw std::invalid_argument("ExactRenderer: no term list");
  if (n_ < stamp_size_) throw std::invalid_argument("ExactRenderer: period below the stamp size");
  if (!bulge_table_ && bulge_index_ != 1.0) throw std::invalid_argument("ExactRenderer: no table for the bulge index");
  const std::size_t spectrum = static_cast<std::size_t>(n_) * terms_->row_stride;
  // Each image's real and imaginary parts in one buffer, the imaginary `spectrum` doubles after
  // the real: FFTW's new-array execute needs the same ii - ri separation as at planning.
  spectrum_size_ = spectrum;
  for (auto& b : spectra_) {
    b = AlignedBuffer(2 * sizeof(double) * spectrum);
    std::memset(b.data(), 0, 2 * sizeof(double) * spectrum);
  }
  grid_ = AlignedBuffer(sizeof(double) * static_cast<std::size_t>(n_) * n_);
  // Split-complex c2r with padded input rows: row stride row_stride, output rows of n.
  fftw_iodim dims[2] = {{n_, terms_->row_stride, n_}, {n_, 1, 1}};
  const unsigned flags = (options.planning == FftPlanning::kMeasure ? FFTW_MEASURE : FFTW_ESTIMATE) | FFTW_DESTROY_INPUT;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan_ = fftw_plan_guru_split_dft_c2r(2, dims, 0, nullptr, spectrum_re(0), spectrum_im(0),
                                         static_cast<double*>(grid_.data()), flags);
  }
  if (!plan_) throw std::runtime_error("FFTW could not plan the exact renderer's inverse transform");
  // FFTW_MEASURE overwrote the planning arrays; the spectra are rewritten every render anyway.
  phase_x_re_.resize(terms_->kx_values.size());
  phase_x_im_.resize(terms_->kx_values.size());
  phase_y_re_.resize(terms_->ky_values.size());
  phase_y_im_.resize(terms_->ky_values.size());
  for (auto& s : component_stamps_) s.assign(static_cast<std::size_t>(stamp_size_) * stamp_size_, 0.0);
}

ExactRenderer::~ExactRenderer() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());  // fftw_destroy_plan is not thread-safe
  fftw_destroy_plan(static_cast<fftw_plan>(plan_));
}

void ExactRenderer::set_terms(std::shared_ptr<const kernels::KSpaceTerms> terms) {
  if (!terms || terms->n != n_ || terms->row_stride != terms_->row_stride ||
      terms->kx_values.size() != terms_->kx_values.size() || terms->ky_values.size() != terms_->ky_values.size())
    throw std::invalid_argument("ExactRenderer::set_terms: a term list for another grid");
  terms_ = std::move(terms);
}

bool ExactRenderer::prepare(const ParamVector& p, kernels::KSpaceModel* m) {
  ModelComponents comp;
  if (!model_.components(p, &comp)) return false;
  const double bulge_n = p[index(Param::kBulgeIndex)], disc_n = p[index(Param::kDiscIndex)];
  if (bulge_n != bulge_index_ || disc_n != 1.0)
    throw std::invalid_argument("ExactRenderer: Sérsic indices other than the tabulated bulge's and 1 for the disc");
  // k-space form W = Q^-1 of the real-space form Q (u = dx^T Q dx), dW/de = -W (dQ/de) W.
  auto fill = [](const kernels::SersicDerivativeBlock& b, double radius, double n, const kernels::SersicKTable* table,
                 kernels::KSpaceComponent* c) {
    const kernels::EllipseQuadratic& q = b.shape.q;
    const double det = q.xx * q.yy - q.xy * q.xy;
    const double wxx = q.yy / det, wxy = -q.xy / det, wyy = q.xx / det;
    auto derivative = [&](const kernels::EllipseQuadratic& d, double* xx, double* xy, double* yy) {
      // (W D W) for symmetric W, D.
      const double a = wxx * d.xx + wxy * d.xy, bb = wxx * d.xy + wxy * d.yy;  // row 0 of W D
      const double c0 = wxy * d.xx + wyy * d.xy, c1 = wxy * d.xy + wyy * d.yy;  // row 1 of W D
      *xx = -(a * wxx + bb * wxy);
      *xy = -(a * wxy + bb * wyy);
      *yy = -(c0 * wxy + c1 * wyy);
    };
    c->table = table;
    c->wxx = wxx;
    c->wxy = wxy;
    c->wyy = wyy;
    derivative(b.dq_de1, &c->e1xx, &c->e1xy, &c->e1yy);
    derivative(b.dq_de2, &c->e2xx, &c->e2xy, &c->e2yy);
    c->flux_per_amplitude = kernels::sersic_flux_per_amplitude(radius, n);
    c->flux = b.amplitude * c->flux_per_amplitude;
  };
  fill(comp.bulge, comp.bulge_radius, bulge_n, bulge_index_ == 1.0 ? nullptr : bulge_table_.get(), &m->bulge);
  fill(comp.disc, comp.disc_radius, disc_n, nullptr, &m->disc);
  m->dlnr = -0.5 * comp.disc.du_dr_over_u;  // du/dr / u = -2 d ln r / dr
  // Phases e^{-i k x0} by recurrence along each alias's run of frequencies (two sincos per axis
  // and alias group instead of one per value; the rounding grows by ~1 ulp per step).
  const double dk = 2 * kPi / n_;
  const double x0 = p[index(Param::kX0)], y0 = p[index(Param::kY0)];
  const int stride = terms_->row_stride;
  const int groups_x = static_cast<int>(terms_->kx_values.size()) / stride;
  const std::complex<double> step_x = std::polar(1.0, -dk * x0), step_y = std::polar(1.0, -dk * y0);
  for (int g = 0; g < groups_x; ++g) {
    std::complex<double> z = std::polar(1.0, -terms_->kx_values[static_cast<std::size_t>(g) * stride] * x0);
    for (int j = 0; j < stride; ++j, z *= step_x) {
      phase_x_re_[static_cast<std::size_t>(g) * stride + j] = z.real();
      phase_x_im_[static_cast<std::size_t>(g) * stride + j] = z.imag();
    }
  }
  const int groups_y = static_cast<int>(terms_->ky_values.size()) / n_;
  for (int g = 0; g < groups_y; ++g) {
    const std::size_t base = static_cast<std::size_t>(g) * n_;
    const std::complex<double> z0 = std::polar(1.0, -terms_->ky_values[base] * y0);  // row 0: ky = 2 pi m
    std::complex<double> z = z0;
    for (int jy = 0; jy <= n_ / 2; ++jy, z *= step_y) {
      phase_y_re_[base + jy] = z.real();
      phase_y_im_[base + jy] = z.imag();
    }
    z = z0 * std::conj(step_y);
    for (int jy = n_ - 1; jy > n_ / 2; --jy, z *= std::conj(step_y)) {
      phase_y_re_[base + jy] = z.real();
      phase_y_im_[base + jy] = z.imag();
    }
  }
  m->phase_x_re = phase_x_re_.data();
  m->phase_x_im = phase_x_im_.data();
  m->phase_y_re = phase_y_re_.data();
  m->phase_y_im = phase_y_im_.data();
  return true;
}

void ExactRenderer::inverse(int k, double* stamp) {
  fftw_execute_split_dft_c2r(static_cast<fftw_plan>(plan_), spectrum_re(k), spectrum_im(k),
                             static_cast<double*>(grid_.data()));
  const double* g = static_cast<const double*>(grid_.data());
  for (int y = 0; y < stamp_size_; ++y)
    std::copy_n(g + static_cast<std::size_t>(y) * n_, stamp_size_, stamp + static_cast<std::size_t>(y) * stamp_size_);
}

RenderStatus ExactRenderer::render(const ParamVector& p, std::span<double> model) {
  kernels::KSpaceModel m;
  if (!prepare(p, &m)) return RenderStatus::kInvalidModel;
  kernels::KSpaceSpectra out;
  out.re[0] = spectrum_re(0);
  out.im[0] = spectrum_im(0);
  kernels_->accumulate_model(*terms_, m, out);
  inverse(0, model.data());
  return RenderStatus::kOk;
}

RenderStatus ExactRenderer::render_with_jacobian(const ParamVector& p, std::span<const Param> free,
                                                 std::span<double> model, std::span<double* const> jacobian) {
  kernels::KSpaceModel m;
  if (!prepare(p, &m)) return RenderStatus::kInvalidModel;
  kernels::KSpaceSpectra out;
  for (int k = 0; k < kernels::kNumKSpaceImages; ++k) {
    out.re[k] = spectrum_re(k);
    out.im[k] = spectrum_im(k);
  }
  kernels_->accumulate_jacobian(*terms_, m, out);
  inverse(kernels::kKBulge, component_stamps_[0].data());
  inverse(kernels::kKDisc, component_stamps_[1].data());
  const double ab = p[index(Param::kBulgeA)], ad = p[index(Param::kDiscA)];
  const auto& bulge = component_stamps_[0];
  const auto& disc = component_stamps_[1];
  for (std::size_t i = 0; i < model.size(); ++i) model[i] = ab * bulge[i] + ad * disc[i];
  for (std::size_t k = 0; k < free.size(); ++k) {
    switch (free[k]) {
      case Param::kX0: inverse(kernels::kKX0, jacobian[k]); break;
      case Param::kY0: inverse(kernels::kKY0, jacobian[k]); break;
      case Param::kE1: inverse(kernels::kKE1, jacobian[k]); break;
      case Param::kE2: inverse(kernels::kKE2, jacobian[k]); break;
      case Param::kRadius: inverse(kernels::kKRadius, jacobian[k]); break;
      case Param::kBulgeA: std::copy(bulge.begin(), bulge.end(), jacobian[k]); break;
      case Param::kDiscA: std::copy(disc.begin(), disc.end(), jacobian[k]); break;
      default: throw std::invalid_argument("render_with_jacobian: parameter has no derivative image");
    }
  }
  return RenderStatus::kOk;
}

}  // namespace stampede
