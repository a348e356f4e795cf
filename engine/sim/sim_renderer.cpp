// The simulator's exact Fourier-space renderer; see sim_renderer.hpp.
#include "engine/sim/sim_renderer.hpp"

#include <fftw3.h>
#include <math.h>  // j0, j1 (glibc)

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <mutex>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "engine/common/parallel_indices.hpp"
#include "kernels/math/fft_size.hpp"
#include "kernels/math/gauss_legendre.hpp"
#include "kernels/math/sinc.hpp"
#include "kernels/sersic.hpp"

namespace stampede {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kPsfTransformFloor = 1e-12;  // aliases are summed out to here
constexpr int kMaxGrid = 2048;

// A fresh SimRenderer::id_ (0 is no renderer's).
std::uint64_t next_renderer_id() {
  static std::atomic<std::uint64_t> last{0};
  return ++last;
}

// Radius beyond which a Sérsic's surface brightness is below 1e-6 of its value at r_e.
double sersic_tail_radius(double n, double hlr) {
  return hlr * std::pow(1.0 + std::log(1e6) / kernels::sersic_b(n), n);
}

}  // namespace

void shear_matrix(double e1, double e2, double s[3]) {
  const double norm = 1.0 / std::sqrt(1.0 - e1 * e1 - e2 * e2);
  s[0] = (1 + e1) * norm;
  s[1] = e2 * norm;
  s[2] = (1 - e1) * norm;
}

// --- workspace ---------------------------------------------------------------------------------

SimWorkspace::~SimWorkspace() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());  // fftw_destroy_plan is not thread-safe
  for (auto& [n, g] : grids_) fftw_destroy_plan(static_cast<fftw_plan>(g.plan));
}

SimWorkspace::Grid& SimWorkspace::grid(int n) {
  auto it = grids_.find(n);
  if (it != grids_.end()) return it->second;
  Grid g;
  g.spectrum = AlignedBuffer(sizeof(fftw_complex) * static_cast<std::size_t>(n) * (n / 2 + 1));
  g.image = AlignedBuffer(sizeof(double) * static_cast<std::size_t>(n) * n);
  {
    // ESTIMATE: deterministic plans, so every thread and run computes bitwise the same image.
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    g.plan = fftw_plan_dft_c2r_2d(n, n, static_cast<fftw_complex*>(g.spectrum.data()),
                                  static_cast<double*>(g.image.data()), FFTW_ESTIMATE);
  }
  if (!g.plan) throw std::runtime_error("FFTW could not plan a " + std::to_string(n) + "^2 inverse transform");
  return grids_.emplace(n, std::move(g)).first->second;
}

// --- renderer -----------------------------------------------------------------------------------

bool SimRenderer::Options::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (sersic_indices.empty()) msg << "sersic_indices: empty";
  for (double n : sersic_indices)
    if (!(n >= 0.5 && n <= 8)) msg << "sersic index " << n << ": must be in [0.5, 8]";
  if (!(max_half_light_radius > 0 && max_half_light_radius <= 100))
    msg << "max_half_light_radius = " << max_half_light_radius << ": must be in (0, 100] pixels";
  if (!(max_e >= 0 && max_e < 0.99)) msg << "max_e = " << max_e << ": must be in [0, 0.99)";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

SimRenderer::SimRenderer(const PsfModel& psf, const Options& options) : psf_(psf), id_(next_renderer_id()) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("SimRenderer: " + why);
  if (!psf.IsValid(&why)) throw std::invalid_argument("SimRenderer PSF: " + why);
  if (psf.kind == PsfKind::kImage)
    throw std::invalid_argument("the simulator draws analytic PSFs only (Moffat, Airy, Gaussian)");
  if (psf.kind == PsfKind::kGaussian) {
    // metacal's reconvolution PSF, drawn as the cell simulator's Gaussian PSF.
    SimGaussianPsf g{psf.gaussian.fwhm, psf.gaussian.e1, psf.gaussian.e2};
    if (!g.IsValid(&why)) throw std::invalid_argument("SimRenderer PSF: " + why);
    set_gaussian(g);
  } else if (psf.kind == PsfKind::kMoffat) {
    const auto& m = psf.moffat;
    psf_alpha_ = kernels::moffat_alpha(m.fwhm, m.beta);
    const double t = m.truncation > 0 ? m.truncation / psf_alpha_ : 0.0;
    // Largest x = k alpha above the floor: scan outwards (a truncated Moffat's transform rings
    // slowly, so it is capped at five aliases of the pixel frequency: 1e-6 of the peak for a
    // truncation at 2.8 FWHM, 1e-5 at 1.4 FWHM).
    const double x_cap = 10 * kPi * psf_alpha_;
    double x_limit = 1.0;
    for (double x = 0.25; x <= x_cap; x += 0.25)
      if (std::abs(kernels::moffat_fourier(m.beta, t, x)) > kPsfTransformFloor) x_limit = x + 0.25;
    x_limit = std::min(x_limit, x_cap);
    // A truncated Moffat's transform oscillates with period ~2 pi / t in x: 400 nodes per decade
    // keep >= 10 nodes per period out to the cap.
    moffat_table_ = kernels::LogTable([&](double x) { return kernels::moffat_fourier(m.beta, t, x); },
                                      kernels::LogGrid::covering(1e-4, x_limit, t > 0 ? 400 : 40));
    k_limit_ = x_limit / psf_alpha_;
    shear_matrix(m.e1, m.e2, psf_shear_);
    const double e = std::hypot(m.e1, m.e2);
    psf_stretch_ = std::sqrt((1 + e) / (1 - e));
    // Light below 1e-7 of the peak: (1 + (r/alpha)^2)^-beta = 1e-7.
    psf_tail_radius_ = psf_alpha_ * std::sqrt(std::pow(1e7, 1.0 / m.beta) - 1.0) * psf_stretch_;
    if (m.truncation > 0) psf_tail_radius_ = std::min(psf_tail_radius_, m.truncation * psf_stretch_);
  } else {
    if (psf.airy.obscuration != 0.0)
      throw std::invalid_argument("the simulator draws unobscured Airy discs only (obscuration = 0)");
    psf_alpha_ = psf.airy.lambda_over_d;
    k_limit_ = 2 * kPi / psf_alpha_;  // the pupil's cut-off: the transform is exactly 0 beyond
    // The Airy envelope 8 L^3 / (pi^4 r^3) of the peak falls to 1e-6 at ~435 L: the r^-3 wings
    // wrapped by a shorter period lift the stamp by ~1e-5 of the peak (1.4e-6 at this period).
    psf_tail_radius_ = psf_alpha_ * std::cbrt(8.0 / (std::pow(kPi, 4) * 1e-6));
  }
  build_sersic_tables(options);
}

bool SimGaussianPsf::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(fwhm > 0 && fwhm <= 1000)) msg << "Gaussian PSF fwhm = " << fwhm << ": must be in (0, 1000] pixels";
  if (!(std::hypot(e1, e2) < 0.9)) msg << "Gaussian PSF |e| = " << std::hypot(e1, e2) << ": must be < 0.9";
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

SimRenderer::SimRenderer(const SimGaussianPsf& psf, const Options& options) : id_(next_renderer_id()) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("SimRenderer: " + why);
  if (!psf.IsValid(&why)) throw std::invalid_argument("SimRenderer PSF: " + why);
  set_gaussian(psf);
  build_sersic_tables(options);
}

void SimRenderer::set_gaussian(const SimGaussianPsf& psf) {
  gaussian_sigma_ = psf.fwhm / (2 * std::sqrt(2 * std::log(2.0)));
  // exp(-x^2 / 2) = 1e-12 at x = sqrt(2 ln 1e12); light below 1e-7 of the peak beyond sqrt(2 ln 1e7).
  k_limit_ = std::sqrt(2 * std::log(1.0 / kPsfTransformFloor)) / gaussian_sigma_;
  shear_matrix(psf.e1, psf.e2, psf_shear_);
  const double e = std::hypot(psf.e1, psf.e2);
  psf_stretch_ = std::sqrt((1 + e) / (1 - e));
  psf_tail_radius_ = gaussian_sigma_ * std::sqrt(2 * std::log(1e7)) * psf_stretch_;
}

void SimRenderer::build_sersic_tables(const Options& options) {
  // Sérsic tables out to the largest q met where the PSF still passes light.
  const double max_stretch = std::sqrt((1 + options.max_e) / (1 - options.max_e));
  const double q_max = std::max(10.0, 1.2 * k_limit_ * psf_stretch_ * max_stretch * options.max_half_light_radius);
  // 40 nodes per decade: interpolation error ~1e-10 of F(0). The high-q nodes cost most (their
  // quadratures follow many Bessel periods), so the nodes are computed in parallel.
  const kernels::LogGrid grid = kernels::LogGrid::covering(1e-4, q_max, 40);
  for (double n : options.sersic_indices) {
    if (n == 1.0) continue;
    std::vector<double> values(static_cast<std::size_t>(grid.count));
    parallel_indices(
        grid.count, 1, [] { return 0; },
        [&](int, long long i) { values[static_cast<std::size_t>(i)] = kernels::sersic_fourier(n, grid.node(static_cast<int>(i))); });
    sersic_tables_.emplace_back(n, kernels::LogTable(grid, std::move(values)));
  }
}

const kernels::LogTable* SimRenderer::table_for(double n) const {
  if (n == 1.0) return nullptr;
  for (const auto& [index, table] : sersic_tables_)
    if (index == n) return &table;
  throw std::invalid_argument("SimRenderer: Sérsic index " + std::to_string(n) + " was not tabulated");
}

double SimRenderer::psf_round_transform(double k) const {
  if (gaussian_sigma_ > 0) {
    const double x = k * gaussian_sigma_;
    return std::exp(-0.5 * x * x);
  }
  if (psf_.kind == PsfKind::kAiry) return kernels::airy_fourier(k * psf_alpha_ / (2 * kPi));
  const double x = k * psf_alpha_;
  return x > moffat_table_.q_max() ? 0.0 : moffat_table_(x);
}

double SimRenderer::psf_transform(double kx, double ky) const {
  if (gaussian_sigma_ == 0 && psf_.kind == PsfKind::kAiry) return psf_round_transform(std::hypot(kx, ky));
  const double sx = psf_shear_[0] * kx + psf_shear_[1] * ky, sy = psf_shear_[1] * kx + psf_shear_[2] * ky;
  return psf_round_transform(std::sqrt(sx * sx + sy * sy));  // no overflow to guard against here
}

double SimRenderer::sersic_transform(const kernels::LogTable* table, double q) {
  return table ? (*table)(q) : kernels::exponential_fourier(q);
}

void SimRenderer::render(std::span<const SimComponent> components, int size, std::span<double> out,
                             SimWorkspace& ws) const {
  double tail = 0;
  for (const SimComponent& c : components) {
    table_for(c.sersic_n);  // throws for an index without a table
    tail = std::max(tail, sersic_tail_radius(c.sersic_n, c.half_light_radius) +
                              std::hypot(c.x - 0.5 * (size - 1), c.y - 0.5 * (size - 1)));
  }
  draw(components, false, size, 1.0, 0, 0, true, tail, out, ws);
}

void SimRenderer::render_psf(int size, double step, double cx, double cy, bool with_pixel, std::span<double> out,
                                 SimWorkspace& ws) const {
  draw({}, true, size, step, cx, cy, with_pixel, 0.0, out, ws);
}

void SimRenderer::draw(std::span<const SimComponent> components, bool psf_only, int size, double step, double cx,
                           double cy, bool with_pixel, double tail_radius, std::span<double> out,
                           SimWorkspace& ws) const {
  if (size < 1 || out.size() != static_cast<std::size_t>(size) * size)
    throw std::invalid_argument("SimRenderer: output does not hold size^2 pixels");
  const double reach = tail_radius + psf_tail_radius_ + 2.0;  // pixels
  const int n = kernels::fft_friendly_size(std::min(kMaxGrid, size + static_cast<int>(std::ceil(reach / step))));
  if (n < size) throw std::invalid_argument("SimRenderer: stamp larger than the largest grid");
  SimWorkspace::Grid& grid = ws.grid(n);
  auto* spectrum = static_cast<std::complex<double>*>(grid.spectrum.data());
  const int half = n / 2 + 1;
  const double dk = 2 * kPi / (n * step), alias = 2 * kPi / step;
  const double k_bound = k_limit_ * psf_stretch_;
  const int m_max = static_cast<int>(std::ceil(k_bound / alias + 0.5));
  const double scale = (with_pixel ? 1.0 / (step * step) : 1.0) / (static_cast<double>(n) * n);
  std::vector<SimWorkspace::Component>& prepared = ws.components_;
  prepared.clear();
  for (const SimComponent& c : components) {
    SimWorkspace::Component p{};
    shear_matrix(c.e1, c.e2, p.s);
    p.flux = c.flux;
    p.hlr = c.half_light_radius;
    p.table = table_for(c.sersic_n);
    prepared.push_back(p);
  }
  // The pixel response and each centre's phase factor into functions of kx and ky alone:
  // tabulated per axis frequency j and alias m (index j * aliases + m + m_max), they replace a
  // sincos per component and two sincs per frequency with products.
  const int aliases = 2 * m_max + 1;
  const std::size_t nx = static_cast<std::size_t>(half) * aliases, ny = static_cast<std::size_t>(n) * aliases;
  const std::size_t phases = psf_only ? 1 : prepared.size();
  ws.sinc_x_.resize(nx);
  ws.sinc_y_.resize(ny);
  ws.phase_x_.resize(nx * phases);
  ws.phase_y_.resize(ny * phases);
  auto axis_k = [&](int j, int m, bool is_y) { return dk * (is_y && j > n / 2 ? j - n : j) + alias * m; };
  for (int axis = 0; axis < 2; ++axis) {
    const bool is_y = axis == 1;
    const int count = is_y ? n : half;
    std::vector<double>& sinc = is_y ? ws.sinc_y_ : ws.sinc_x_;
    std::vector<std::complex<double>>& phase = is_y ? ws.phase_y_ : ws.phase_x_;
    const std::size_t stride = is_y ? ny : nx;
    for (int j = 0; j < count; ++j)
      for (int m = -m_max; m <= m_max; ++m) {
        const std::size_t i = static_cast<std::size_t>(j) * aliases + (m + m_max);
        const double k = axis_k(j, m, is_y);
        sinc[i] = with_pixel ? kernels::sinc(0.5 * k) : 1.0;
        if (psf_only) {
          phase[i] = std::polar(1.0, -k * (is_y ? cy : cx) * step);
        } else {
          for (std::size_t c = 0; c < prepared.size(); ++c)
            phase[c * stride + i] = std::polar(1.0, -k * (is_y ? components[c].y : components[c].x));
        }
      }
  }
  // The galaxy's transform at (kx, ky): its components' profiles at their shapes and positions.
  auto galaxy = [&](double kx, double ky, std::size_t ix, std::size_t iy) {
    std::complex<double> gal = 0;
    for (std::size_t c = 0; c < prepared.size(); ++c) {
      const SimWorkspace::Component& p = prepared[c];
      const double u = p.s[0] * kx + p.s[1] * ky, v = p.s[1] * kx + p.s[2] * ky;
      gal += p.flux * sersic_transform(p.table, std::sqrt(u * u + v * v) * p.hlr) *
             (ws.phase_x_[c * nx + ix] * ws.phase_y_[c * ny + iy]);
    }
    return gal;
  };
  if (!psf_only && with_pixel && step == 1.0) {
    // A galaxy's draw: the terms below with the PSF's factors from the workspace.
    const SimWorkspace::PsfTerms& terms = galaxy_psf_terms(n, ws);
    const std::size_t frequencies = static_cast<std::size_t>(n) * half;
    std::size_t t = 0;
    for (std::size_t f = 0; f < frequencies; ++f) {
      std::complex<double> sum = 0;
      for (const std::size_t end = terms.end[f]; t < end; ++t) {
        const std::size_t ix = terms.ix[t], iy = terms.iy[t];
        const double kx = terms.k_x[ix], ky = terms.k_y[iy];
        sum += terms.psf[t] * galaxy(kx, ky, ix, iy);
      }
      spectrum[f] = sum * scale;
    }
  } else {
    for (int jy = 0; jy < n; ++jy) {
      for (int jx = 0; jx < half; ++jx) {
        std::complex<double> sum = 0;
        for (int my = -m_max; my <= m_max; ++my) {
          const std::size_t iy = static_cast<std::size_t>(jy) * aliases + (my + m_max);
          const double ky = axis_k(jy, my, true);
          if (std::abs(ky) > k_bound) continue;
          for (int mx = -m_max; mx <= m_max; ++mx) {
            const std::size_t ix = static_cast<std::size_t>(jx) * aliases + (mx + m_max);
            const double kx = axis_k(jx, mx, false);
            if (kx * kx + ky * ky > k_bound * k_bound) continue;
            double psf = psf_transform(kx, ky);
            if (psf == 0.0) continue;
            psf *= ws.sinc_x_[ix] * ws.sinc_y_[iy];
            if (psf_only) {
              sum += psf * (ws.phase_x_[ix] * ws.phase_y_[iy]);
              continue;
            }
            sum += psf * galaxy(kx, ky, ix, iy);
          }
        }
        spectrum[static_cast<std::size_t>(jy) * half + jx] = sum * scale;
      }
    }
  }
  fftw_execute_dft_c2r(static_cast<fftw_plan>(grid.plan), reinterpret_cast<fftw_complex*>(spectrum),
                       static_cast<double*>(grid.image.data()));
  const double* image = static_cast<const double*>(grid.image.data());
  for (int y = 0; y < size; ++y)
    std::copy_n(image + static_cast<std::size_t>(y) * n, size, out.data() + static_cast<std::size_t>(y) * size);
}

const SimWorkspace::PsfTerms& SimRenderer::galaxy_psf_terms(int n, SimWorkspace& ws) const {
  if (ws.psf_terms_renderer_ != id_) {
    ws.psf_terms_.clear();
    ws.psf_terms_renderer_ = id_;
  }
  if (auto it = ws.psf_terms_.find(n); it != ws.psf_terms_.end()) return it->second;
  // draw()'s loop at step 1 with the pixel, its expressions unchanged so that the values are the same.
  const double step = 1.0;
  const int half = n / 2 + 1;
  const double dk = 2 * kPi / (n * step), alias = 2 * kPi / step;
  const double k_bound = k_limit_ * psf_stretch_;
  const int m_max = static_cast<int>(std::ceil(k_bound / alias + 0.5));
  const int aliases = 2 * m_max + 1;
  auto axis_k = [&](int j, int m, bool is_y) { return dk * (is_y && j > n / 2 ? j - n : j) + alias * m; };
  SimWorkspace::PsfTerms t;
  t.k_x.resize(static_cast<std::size_t>(half) * aliases);
  t.k_y.resize(static_cast<std::size_t>(n) * aliases);
  std::vector<double> sinc_x(t.k_x.size()), sinc_y(t.k_y.size());
  for (int j = 0; j < n; ++j)
    for (int m = -m_max; m <= m_max; ++m) {
      const std::size_t i = static_cast<std::size_t>(j) * aliases + (m + m_max);
      if (j < half) {
        t.k_x[i] = axis_k(j, m, false);
        sinc_x[i] = kernels::sinc(0.5 * t.k_x[i]);
      }
      t.k_y[i] = axis_k(j, m, true);
      sinc_y[i] = kernels::sinc(0.5 * t.k_y[i]);
    }
  t.end.reserve(static_cast<std::size_t>(n) * half);
  for (int jy = 0; jy < n; ++jy)
    for (int jx = 0; jx < half; ++jx) {
      for (int my = -m_max; my <= m_max; ++my) {
        const std::size_t iy = static_cast<std::size_t>(jy) * aliases + (my + m_max);
        const double ky = t.k_y[iy];
        if (std::abs(ky) > k_bound) continue;
        for (int mx = -m_max; mx <= m_max; ++mx) {
          const std::size_t ix = static_cast<std::size_t>(jx) * aliases + (mx + m_max);
          const double kx = t.k_x[ix];
          if (kx * kx + ky * ky > k_bound * k_bound) continue;
          double psf = psf_transform(kx, ky);
          if (psf == 0.0) continue;
          psf *= sinc_x[ix] * sinc_y[iy];
          t.psf.push_back(psf);
          t.ix.push_back(static_cast<std::uint32_t>(ix));
          t.iy.push_back(static_cast<std::uint32_t>(iy));
        }
      }
      t.end.push_back(static_cast<std::uint32_t>(t.psf.size()));
    }
  return ws.psf_terms_.emplace(n, std::move(t)).first->second;
}

double SimRenderer::round_fwhm(std::span<const SimComponent> components) const {
  return RoundFwhmSolver(*this, false)(components);
}

RoundFwhmSolver::RoundFwhmSolver(const SimRenderer& renderer, bool bracket_tables) : renderer_(renderer) {
  // I(r) = (1/2pi) Integral F(k) J0(k r) k dk over [0, k_limit], as sum_i c_i J0(k_i r) with
  // Gauss-Legendre panels of width 0.05 / pixel (a quarter period of J0 at r = 30 px).
  constexpr double kPanel = 0.05;
  for (double a = 0; a < renderer.k_limit_; a += kPanel) {
    const double mid = a + 0.5 * kPanel, h = 0.5 * kPanel;
    const kernels::GaussLegendre12& gl = kernels::gauss_legendre_12();
    for (int i = 0; i < kernels::GaussLegendre12::kN; ++i) {
      const double k = mid + h * gl.x[i];
      nodes_.push_back(k);
      weights_.push_back(gl.w[i] * h * k);
    }
  }
  if (!bracket_tables) return;
  auto bessel = [&](double (*fn)(double), double r) {
    std::vector<double> v(nodes_.size());
    for (std::size_t i = 0; i < nodes_.size(); ++i) v[i] = fn(nodes_[i] * r);
    return v;
  };
  double lo = 0, hi = 0.25;  // the solve's bracket, doubled as it does
  for (int j = 0; j < kTabulatedDoublings; ++j) {
    const double middle = 0.5 * (lo + hi);
    j0_doubling_.push_back(bessel(::j0, hi));
    j0_middle_.push_back(bessel(::j0, middle));
    j1_middle_.push_back(bessel(::j1, middle));
    lo = hi;
    hi *= 2;
  }
}

double RoundFwhmSolver::operator()(std::span<const SimComponent> components) const {
  std::vector<const kernels::LogTable*> tables;
  for (const SimComponent& c : components) tables.push_back(renderer_.table_for(c.sersic_n));
  std::vector<double> coeffs(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const double k = nodes_[i];
    double f = renderer_.psf_round_transform(k);
    if (!components.empty()) {
      double g = 0;
      for (std::size_t c = 0; c < components.size(); ++c)
        g += components[c].flux * SimRenderer::sersic_transform(tables[c], k * components[c].half_light_radius);
      f *= g;
    }
    coeffs[i] = weights_[i] * f;
  }
  // J0 and J1 from a table when one holds them at r, else evaluated.
  auto intensity = [&](double r, const std::vector<double>* j0_at_r) {
    double s = 0;
    for (std::size_t i = 0; i < nodes_.size(); ++i) s += coeffs[i] * (j0_at_r ? (*j0_at_r)[i] : ::j0(nodes_[i] * r));
    return s;
  };
  auto slope = [&](double r, const std::vector<double>* j1_at_r) {
    double s = 0;
    for (std::size_t i = 0; i < nodes_.size(); ++i)
      s -= coeffs[i] * nodes_[i] * (j1_at_r ? (*j1_at_r)[i] : ::j1(nodes_[i] * r));
    return s;
  };
  const auto tabulated = [&](const std::vector<std::vector<double>>& table, int j) {
    return j < static_cast<int>(table.size()) ? &table[static_cast<std::size_t>(j)] : nullptr;
  };
  // J0(0) = 1 exactly: the peak is the sum of the coefficients.
  double peak = 0;
  for (double c : coeffs) peak += c;
  const double target = 0.5 * peak;
  double lo = 0, hi = 0.25;
  int doubling = 0;
  while (intensity(hi, tabulated(j0_doubling_, doubling)) > target) {
    lo = hi;
    hi *= 2;
    ++doubling;
    if (hi > 1e3) throw std::runtime_error("round_fwhm: the profile does not fall to half maximum");
  }
  // Newton from the bracket's middle, falling back to bisection when a step leaves the bracket.
  const double middle = 0.5 * (lo + hi);
  double r = middle;
  for (int it = 0; it < 100 && hi - lo > 1e-12 * hi; ++it) {
    const bool at_middle = it == 0;
    const double f = intensity(r, at_middle ? tabulated(j0_middle_, doubling) : nullptr) - target;
    (f > 0 ? lo : hi) = r;
    const double d = slope(r, at_middle ? tabulated(j1_middle_, doubling) : nullptr);
    double next = d < 0 ? r - f / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - r) < 1e-13 * r) {
      r = next;
      break;
    }
    r = next;
  }
  return 2 * r;
}

}  // namespace stampede
