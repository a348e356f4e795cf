// The exact Fourier-space fitting renderer; see exact_renderer.hpp.
#include "engine/render/exact_renderer.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <functional>
#include <map>
#include <mutex>
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
// Wrap-correction images: bulge, disc, then the five shape derivatives.
constexpr int kWrapImages = 2 + kernels::kWingDerivatives;

}  // namespace


int exact_period(int stamp_size) { return kernels::fft_friendly_size(stamp_size + kExactPeriodMargin); }

int exact_surrogate_period(int stamp_size) { return kernels::fft_friendly_size(stamp_size + kSurrogatePeriodMargin); }

int exact_uncorrected_period(int stamp_size) { return kernels::fft_friendly_size(4 * stamp_size); }

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
  // at |e| = 0.95 (stretch 6.2). Beyond, the power law through the last two nodes, checked against
  // the quadrature to q = 6,000 (docs/performance.md, "The exact renderer's constants").
  static const std::shared_ptr<const kernels::SersicKTable> table = build_sersic_k_table(4.0, 2000.0);
  return table;
}

std::shared_ptr<const kernels::SersicKTable> sersic_k_table(double n) {
  if (n == 4.0) return de_vaucouleurs_k_table();
  static std::mutex mutex;
  static std::map<double, std::shared_ptr<const kernels::SersicKTable>> tables;
  std::lock_guard<std::mutex> lock(mutex);
  auto& t = tables[n];
  if (!t) t = build_sersic_k_table(n, 2000.0);
  return t;
}

ExactRenderer::ExactRenderer(const RenderOptions& render, const ModelOptions& model)
    : stamp_size_(render.stamp_size),
      n_(render.exact.period > 0 ? render.exact.period : exact_period(render.stamp_size)),
      options_(render.exact),
      model_(model, 1.0 / render.upsampling),
      kernels_(&kernels::kspace_kernels(render.simd)),
      wrap_kernels_(&kernels::wrap_kernels(render.simd)) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument("ExactRenderer: " + why);
  // The de Vaucouleurs table (the default bulge) is built here, with the renderer, rather than
  // inside the first fit (once per process, but longer than many fits), so no fit's time_us
  // carries it.
  bulge_table_ = de_vaucouleurs_k_table();
  bulge_index_ = 4.0;
  if (stamp_size_ < 1) throw std::invalid_argument("ExactRenderer: stamp_size must be positive");
  if (n_ < stamp_size_) throw std::invalid_argument("ExactRenderer: exact_period is below the stamp size");
  // The grid's shape is the term lists' (kernels::KSpaceTerms): rows of n / 2 + 1 padded to kKBlock.
  row_stride_ = (n_ / 2 + 1 + kernels::kKBlock - 1) / kernels::kKBlock * kernels::kKBlock;
  spectrum_size_ = static_cast<std::size_t>(n_) * row_stride_;
  // Each image's real and imaginary parts in one buffer, the imaginary `spectrum` doubles after the real.
  for (auto& b : spectra_) {
    b = AlignedBuffer(2 * sizeof(double) * spectrum_size_);
    std::memset(b.data(), 0, 2 * sizeof(double) * spectrum_size_);
  }
  grid_ = AlignedBuffer(sizeof(double) * static_cast<std::size_t>(stamp_size_) * n_);
  // FFTW's interleaved complex values: its c2r plans for them run faster than a split-complex
  // guru plan over the kernels' padded rows, so each spectrum is interleaved before its inverse,
  // and transposed on the way: the columns' transforms then read contiguous columns (a strided
  // column plan copies them through buffers; docs/performance.md).
  const int half = n_ / 2 + 1;
  complex_ = AlignedBuffer(sizeof(fftw_complex) * static_cast<std::size_t>(n_) * half);
  columns_ = AlignedBuffer(sizeof(fftw_complex) * static_cast<std::size_t>(n_) * half);
  // FFTW_ESTIMATE: plans (hence rounding) independent of timing, so fits are bitwise repeatable.
  // The inverse is pruned to the stamp: the c2c transforms of the half-spectrum's columns, then
  // c2r transforms of only the stamp_size rows the stamp is cut from (a 2-D plan would transform
  // all n).
  const unsigned flags = FFTW_ESTIMATE | FFTW_DESTROY_INPUT;
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    auto* c = static_cast<fftw_complex*>(complex_.data());
    auto* t = static_cast<fftw_complex*>(columns_.data());
    column_plan_ = fftw_plan_many_dft(1, &n_, half, c, nullptr, 1, n_, t, nullptr, 1, n_, FFTW_BACKWARD, flags);
    row_plan_ = fftw_plan_many_dft_c2r(1, &n_, stamp_size_, t, nullptr, n_, 1, static_cast<double*>(grid_.data()),
                                       nullptr, 1, n_, flags);
  }
  if (!column_plan_ || !row_plan_) throw std::runtime_error("FFTW could not plan the exact renderer's inverse transform");
  for (auto& s : component_stamps_) s.assign(static_cast<std::size_t>(stamp_size_) * stamp_size_, 0.0);
  for (auto& s : position_stamps_) s.assign(static_cast<std::size_t>(stamp_size_) * stamp_size_, 0.0);
  bin_x_re_.assign(static_cast<std::size_t>(row_stride_), 0.0);
  bin_x_im_.assign(static_cast<std::size_t>(row_stride_), 0.0);
  bin_y_re_.assign(static_cast<std::size_t>(n_), 0.0);
  bin_y_im_.assign(static_cast<std::size_t>(n_), 0.0);
  if (options_.wrap_rings > 0) {
    const std::size_t copies = static_cast<std::size_t>(2 * options_.wrap_rings + 1) * (2 * options_.wrap_rings + 1);
    wrap_[0] = WrapGrid(stamp_size_, options_.wrap_nodes, render.simd, copies);
    wrap_[1] = WrapGrid(stamp_size_, std::min(options_.wrap_nodes, kFarWrapNodes), render.simd, copies);
  }
  if (options_.surrogate) {
    RenderOptions coarse = render;
    coarse.exact.surrogate = false;
    coarse.exact.period = options_.surrogate_period > 0 ? options_.surrogate_period : exact_surrogate_period(stamp_size_);
    coarse.exact.psf_tolerance = options_.surrogate_psf_tolerance;
    coarse.exact.wrap_rings = options_.surrogate_wrap_rings;
    coarse.exact.wrap_nodes = options_.surrogate_wrap_nodes;
    // A surrogate no cheaper than this renderer is none.
    if (coarse.exact.period < n_ || coarse.exact.psf_tolerance > options_.psf_tolerance)
      surrogate_ = std::make_unique<ExactRenderer>(coarse, model);
  }
}

ExactRenderer::WrapGrid::WrapGrid(int stamp_size, int nodes, kernels::Isa isa, std::size_t copies)
    : grid(stamp_size, nodes, isa) {
  for (int jy = 0; jy < nodes; ++jy)
    for (int jx = 0; jx < nodes; ++jx) {
      node_x.push_back(grid.node(jx));
      node_y.push_back(grid.node(jy));
    }
  values.assign(static_cast<std::size_t>(kWrapImages) * nodes * nodes, 0.0);
  scratch.assign(static_cast<std::size_t>(nodes) * stamp_size, 0.0);
  bulge.reserve(copies);
  disc.reserve(copies);
}

ExactRenderer::~ExactRenderer() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());  // fftw_destroy_plan is not thread-safe
  fftw_destroy_plan(static_cast<fftw_plan>(row_plan_));
  fftw_destroy_plan(static_cast<fftw_plan>(column_plan_));
}

std::shared_ptr<const PreparedPsf> ExactRenderer::prepare_psf(const PsfModel& psf, std::string* error) {
  auto prepared = build_exact_psf(psf, n_, options_.psf_tolerance, error);
  if (!prepared) return nullptr;
  if (!prepared->finite_blur() && n_ < exact_uncorrected_period(stamp_size_)) {
    if (error) {
      std::ostringstream msg;
      msg << "the exact renderer cannot subtract the wrapped light of a PSF whose second moments diverge (the Airy "
             "disc, Moffat beta <= 2) on its "
          << n_ << "-pixel period: set exact_period >= " << exact_uncorrected_period(stamp_size_)
          << " or renderer = upsampled";
      *error = msg.str();
    }
    return nullptr;
  }
  if (!surrogate_) return prepared;
  // The surrogate's own preparation of the PSF; a PSF it cannot take is fitted without one.
  std::string ignored;
  auto coarse = std::dynamic_pointer_cast<const ExactPsf>(surrogate_->prepare_psf(psf, &ignored));
  if (!coarse) return prepared;
  return std::make_shared<const ExactPsf>(*prepared, std::move(coarse));
}

void ExactRenderer::set_psf(std::shared_ptr<const PreparedPsf> psf) {
  auto exact = std::dynamic_pointer_cast<const ExactPsf>(psf);
  if (!exact) throw std::invalid_argument("ExactRenderer::set_psf: a PSF prepared by another renderer kind");
  const kernels::KSpaceTerms& t = exact->terms();
  if (t.n != n_ || t.row_stride != row_stride_)
    throw std::invalid_argument("ExactRenderer::set_psf: a PSF prepared for another period");
  // The alias phase table follows the term list's alias count, fixed per PSF: sized here, once
  // per distinct count (a PSF cache's PSFs of one kind share it).
  const std::size_t pairs = static_cast<std::size_t>(t.aliases()) * t.aliases();
  if (alias_re_.size() != pairs) {
    alias_re_.resize(pairs);
    alias_im_.resize(pairs);
  }
  if (surrogate_ && exact->surrogate()) surrogate_->set_psf(exact->surrogate());
  psf_ = std::move(exact);
}

bool ExactRenderer::effective_params(const ParamVector& p, ParamVector* out) const {
  return model_.effective_params(p, out);
}

void ExactRenderer::component_fluxes(const ParamVector& p, double* bulge, double* disc) const {
  model_.fluxes(p, bulge, disc);
}

void ExactRenderer::set_frame(const PixelFrame& frame) {
  frame_ = frame;
  pixel_area_ = frame.identity() ? 1.0 : std::abs(frame.determinant());
  if (surrogate_) surrogate_->set_frame(frame);
}

void ExactRenderer::to_frame_pixels(ModelComponents* comp) const {
  if (frame_.identity()) return;
  for (kernels::SersicDerivativeBlock* b : {&comp->bulge, &comp->disc}) {
    frame_.to_pixel(b->shape.x0, b->shape.y0, &b->shape.x0, &b->shape.y0);
    b->shape.q = frame_.to_pixel(b->shape.q);
    b->dq_de1 = frame_.to_pixel(b->dq_de1);
    b->dq_de2 = frame_.to_pixel(b->dq_de2);
  }
  // The radii and amplitudes stay the model's: they set the flux, which the frame keeps. The wrap's
  // real-space wings, per pixel, scale them by the pixel's area (pixel_area_).
}

bool ExactRenderer::prepare(const ParamVector& p, kernels::KSpaceModel* m, ModelComponents* comp) {
  if (!model_.components(p, comp)) return false;
  to_frame_pixels(comp);
  const double bulge_n = p[index(Param::kBulgeIndex)], disc_n = p[index(Param::kDiscIndex)];
  if (disc_n != 1.0) throw std::invalid_argument("ExactRenderer: a disc index other than 1");
  if (bulge_n != bulge_index_) {  // once per run: the index is fixed by the options
    bulge_table_ = bulge_n == 1.0 ? nullptr : sersic_k_table(bulge_n);
    bulge_index_ = bulge_n;
  }
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
  fill(comp->bulge, comp->bulge_radius, bulge_n, bulge_table_.get(), &m->bulge);
  fill(comp->disc, comp->disc_radius, disc_n, nullptr, &m->disc);
  m->dlnr = -0.5 * comp->disc.du_dr_over_u;  // du/dr / u = -2 d ln r / dr
  // Phases: the bins' e^{-i k0 x0} by recurrence along each axis (two sincos per axis instead of
  // one per value; the rounding grows by ~1 ulp per step), and each alias's e^{-i 2 pi m.x0}.
  const kernels::KSpaceTerms& terms = psf_->terms();
  const double dk = 2 * kPi / n_;
  double x0 = p[index(Param::kX0)], y0 = p[index(Param::kY0)];
  if (!frame_.identity()) frame_.to_pixel(x0, y0, &x0, &y0);
  const std::complex<double> step_x = std::polar(1.0, -dk * x0), step_y = std::polar(1.0, -dk * y0);
  std::complex<double> z = 1.0;
  for (int j = 0; j < row_stride_; ++j, z *= step_x) {
    bin_x_re_[static_cast<std::size_t>(j)] = z.real();
    bin_x_im_[static_cast<std::size_t>(j)] = z.imag();
  }
  z = 1.0;
  for (int jy = 0; jy <= n_ / 2; ++jy, z *= step_y) {
    bin_y_re_[static_cast<std::size_t>(jy)] = z.real();
    bin_y_im_[static_cast<std::size_t>(jy)] = z.imag();
  }
  z = std::conj(step_y);
  for (int jy = n_ - 1; jy > n_ / 2; --jy, z *= std::conj(step_y)) {
    bin_y_re_[static_cast<std::size_t>(jy)] = z.real();
    bin_y_im_[static_cast<std::size_t>(jy)] = z.imag();
  }
  const int aliases = terms.aliases();
  for (int ax = 0; ax < aliases; ++ax)
    for (int ay = 0; ay < aliases; ++ay) {
      const double phase = -2 * kPi * ((ax - terms.alias_max) * x0 + (ay - terms.alias_max) * y0);
      const std::size_t i = static_cast<std::size_t>(ax) * aliases + ay;
      alias_re_[i] = std::cos(phase);
      alias_im_[i] = std::sin(phase);
    }
  m->bin_phase_x_re = bin_x_re_.data();
  m->bin_phase_x_im = bin_x_im_.data();
  m->bin_phase_y_re = bin_y_re_.data();
  m->bin_phase_y_im = bin_y_im_.data();
  m->alias_phase_re = alias_re_.data();
  m->alias_phase_im = alias_im_.data();
  return true;
}

void ExactRenderer::apply_bin_factor(int k) {
  if (!psf_->has_bin_factor()) return;
  double* re = spectrum_re(k);
  double* im = spectrum_im(k);
  const double* dr = psf_->bin_re();
  const double* di = psf_->bin_im();
  for (std::size_t i = 0; i < spectrum_size_; ++i) {
    const double a = re[i], b = im[i];
    re[i] = a * dr[i] - b * di[i];
    im[i] = a * di[i] + b * dr[i];
  }
}

void ExactRenderer::inverse(int k, double* stamp) {
  apply_bin_factor(k);
  const int half = n_ / 2 + 1;
  auto* c = static_cast<double*>(complex_.data());
  const double* re = spectrum_re(k);
  const double* im = spectrum_im(k);
  for (int jy = 0; jy < n_; ++jy) {
    const double* r = re + static_cast<std::size_t>(jy) * row_stride_;
    const double* i = im + static_cast<std::size_t>(jy) * row_stride_;
    double* o = c + 2 * static_cast<std::size_t>(jy);
    for (int jx = 0; jx < half; ++jx) {
      o[2 * static_cast<std::size_t>(jx) * n_] = r[jx];
      o[2 * static_cast<std::size_t>(jx) * n_ + 1] = i[jx];
    }
  }
  fftw_execute(static_cast<fftw_plan>(column_plan_));
  fftw_execute(static_cast<fftw_plan>(row_plan_));
  const double* g = static_cast<const double*>(grid_.data());
  for (int y = 0; y < stamp_size_; ++y)
    std::copy_n(g + static_cast<std::size_t>(y) * n_, stamp_size_, stamp + static_cast<std::size_t>(y) * stamp_size_);
}

namespace {

kernels::WingComponent wing_of(const kernels::SersicDerivativeBlock& b) {
  kernels::WingComponent w;
  w.x0 = b.shape.x0;
  w.y0 = b.shape.y0;
  w.q = b.shape.q;
  w.b = b.shape.b;
  w.s = b.shape.inv_2n;
  w.root = b.shape.root;
  w.dq_de1 = b.dq_de1;
  w.dq_de2 = b.dq_de2;
  w.du_dr_over_u = b.du_dr_over_u;
  return w;
}

}  // namespace

void ExactRenderer::find_copies(const ModelComponents& comp, const kernels::KSpaceModel& m) {
  const kernels::BlurMoments& blur_m = psf_->blur();
  const double blur = 0.5 * (blur_m.xx + blur_m.yy);
  auto find = [&](const kernels::SersicDerivativeBlock& b, double model_radius, double flux_per_amplitude,
                  std::vector<kernels::CopyOffset> WrapGrid::*list) {
    const double radius = model_radius / std::sqrt(pixel_area_);  // in pixels
    // Copies below 1e-8 of the component's blurred peak (flux / (2 pi (r^2 + sigma^2)), unit
    // amplitude) are left out: even fifty of them stay below 5e-7 of it.
    const double peak = flux_per_amplitude / (2 * kPi * (radius * radius + blur));
    std::vector<kernels::CopyOffset>& near = wrap_[0].*list;
    std::vector<kernels::CopyOffset>& far = wrap_[1].*list;
    kernels::significant_copies(wing_of(b), n_, stamp_size_, options_.wrap_rings, 1e-8 * std::min(1.0, peak), &near);
    // The first ring stays on the fine grid, the rest moves to the coarse one, in order (no
    // std::stable_partition: it allocates).
    far.clear();
    const double ring_edge = 1.5 * n_;
    std::size_t kept = 0;
    for (const kernels::CopyOffset& c : near) {
      if (std::abs(c.dx) < ring_edge && std::abs(c.dy) < ring_edge)
        near[kept++] = c;
      else
        far.push_back(c);
    }
    near.resize(kept);
  };
  find(comp.bulge, comp.bulge_radius, m.bulge.flux_per_amplitude, &WrapGrid::bulge);
  find(comp.disc, comp.disc_radius, m.disc.flux_per_amplitude, &WrapGrid::disc);
}

void ExactRenderer::subtract_wrap(const ModelComponents& comp, const kernels::KSpaceModel& m, double* model) {
  find_copies(comp, m);
  for (WrapGrid& w : wrap_) {
    if (w.bulge.empty() && w.disc.empty()) continue;
    const int count = w.grid.nodes() * w.grid.nodes();
    double* v = w.values.data();
    std::fill_n(v, count, 0.0);
    auto add = [&](const kernels::SersicDerivativeBlock& b, const std::vector<kernels::CopyOffset>& copies) {
      if (copies.empty() || b.amplitude == 0) return;
      wrap_kernels_->add_wings(wing_of(b), psf_->blur(), copies.data(), static_cast<int>(copies.size()),
                               w.node_x.data(), w.node_y.data(), count, -b.amplitude * pixel_area_, v, 0.0, nullptr);
    };
    add(comp.bulge, w.bulge);
    add(comp.disc, w.disc);
    w.grid.add_interpolated(v, model, w.scratch.data());
  }
}

void ExactRenderer::subtract_wrap(const ModelComponents& comp, const kernels::KSpaceModel& m, double* bulge_image,
                                  double* disc_image, const std::array<double*, 5>& shape) {
  find_copies(comp, m);
  for (WrapGrid& w : wrap_) {
    if (w.bulge.empty() && w.disc.empty()) continue;
    const int count = w.grid.nodes() * w.grid.nodes();
    const std::size_t per = static_cast<std::size_t>(count);
    double* v = w.values.data();  // kWrapImages blocks: bulge, disc, then the five derivatives
    std::fill_n(v, kWrapImages * per, 0.0);
    std::array<double*, kernels::kWingDerivatives> d;
    for (int k = 0; k < kernels::kWingDerivatives; ++k) d[static_cast<std::size_t>(k)] = v + (2 + k) * per;
    const bool derivatives = std::any_of(shape.begin(), shape.end(), [](const double* s) { return s != nullptr; });
    auto add = [&](const kernels::SersicDerivativeBlock& b, const std::vector<kernels::CopyOffset>& copies,
                   double* image) {
      if (copies.empty()) return;
      // The component image per unit amplitude; the shape derivatives at the model's amplitude.
      wrap_kernels_->add_wings(wing_of(b), psf_->blur(), copies.data(), static_cast<int>(copies.size()),
                               w.node_x.data(), w.node_y.data(), count, -pixel_area_, image, -b.amplitude * pixel_area_,
                               derivatives ? d.data() : nullptr);
    };
    add(comp.bulge, w.bulge, v);
    add(comp.disc, w.disc, v + per);
    double* scratch = w.scratch.data();
    if (!w.bulge.empty()) w.grid.add_interpolated(v, bulge_image, scratch);
    if (!w.disc.empty()) w.grid.add_interpolated(v + per, disc_image, scratch);
    for (int k = 0; k < kernels::kWingDerivatives; ++k)
      if (shape[static_cast<std::size_t>(k)])
        w.grid.add_interpolated(v + (2 + k) * per, shape[static_cast<std::size_t>(k)], scratch);
  }
}

RenderStatus ExactRenderer::render(const ParamVector& p, std::span<double> model) {
  if (!psf_) return RenderStatus::kNoPsf;
  kernels::KSpaceModel m;
  ModelComponents comp;
  if (!prepare(p, &m, &comp)) return RenderStatus::kInvalidModel;
  kernels::KSpaceSpectra out;
  out.re[0] = spectrum_re(0);
  out.im[0] = spectrum_im(0);
  kernels_->accumulate_model(psf_->terms(), m, out);
  inverse(0, model.data());
  if (corrects_wrap()) subtract_wrap(comp, m, model.data());
  return RenderStatus::kOk;
}

RenderStatus ExactRenderer::render_components(const ParamVector& p, std::span<double> bulge, std::span<double> disc) {
  if (!psf_) return RenderStatus::kNoPsf;
  kernels::KSpaceModel m;
  ModelComponents comp;
  if (!prepare(p, &m, &comp)) return RenderStatus::kInvalidModel;
  kernels::KSpaceSpectra out;
  for (int k : {kernels::kKBulge, kernels::kKDisc}) {
    out.re[k] = spectrum_re(k);
    out.im[k] = spectrum_im(k);
  }
  kernels_->accumulate_components(psf_->terms(), m, out);
  inverse(kernels::kKBulge, bulge.data());
  inverse(kernels::kKDisc, disc.data());
  if (corrects_wrap()) subtract_wrap(comp, m, bulge.data(), disc.data(), {});
  return RenderStatus::kOk;
}

RenderStatus ExactRenderer::render_with_jacobian(const ParamVector& p, std::span<const Param> free,
                                                 std::span<double> model, std::span<double* const> jacobian) {
  if (!psf_) return RenderStatus::kNoPsf;
  kernels::KSpaceModel m;
  ModelComponents comp;
  if (!prepare(p, &m, &comp)) return RenderStatus::kInvalidModel;
  kernels::KSpaceSpectra out;
  for (int k = 0; k < kernels::kNumKSpaceImages; ++k) {
    out.re[k] = spectrum_re(k);
    out.im[k] = spectrum_im(k);
  }
  kernels_->accumulate_jacobian(psf_->terms(), m, out);
  inverse(kernels::kKBulge, component_stamps_[0].data());
  inverse(kernels::kKDisc, component_stamps_[1].data());
  std::array<double*, 5> shape{};  // x0, y0, e1, e2, radius images, where wanted
  // In a frame, d/du0 and d/dv0 mix both pixel derivatives: draw both into scratch.
  const bool framed_position =
      !frame_.identity() && std::any_of(free.begin(), free.end(), [](Param q) { return q == Param::kX0 || q == Param::kY0; });
  if (framed_position) {
    inverse(kernels::kKX0, shape[0] = position_stamps_[0].data());
    inverse(kernels::kKY0, shape[1] = position_stamps_[1].data());
  }
  for (std::size_t k = 0; k < free.size(); ++k) {
    switch (free[k]) {
      case Param::kX0:
        if (!framed_position) inverse(kernels::kKX0, shape[0] = jacobian[k]);
        break;
      case Param::kY0:
        if (!framed_position) inverse(kernels::kKY0, shape[1] = jacobian[k]);
        break;
      case Param::kE1: inverse(kernels::kKE1, shape[2] = jacobian[k]); break;
      case Param::kE2: inverse(kernels::kKE2, shape[3] = jacobian[k]); break;
      case Param::kRadius: inverse(kernels::kKRadius, shape[4] = jacobian[k]); break;
      case Param::kBulgeA:
      case Param::kDiscA: break;
      default: throw std::invalid_argument("render_with_jacobian: parameter has no derivative image");
    }
  }
  if (corrects_wrap()) subtract_wrap(comp, m, component_stamps_[0].data(), component_stamps_[1].data(), shape);
  if (framed_position) {
    double inv[2][2];  // d(x, y) / d(u, v)
    frame_.inverse(inv);
    const double* dx = position_stamps_[0].data();
    const double* dy = position_stamps_[1].data();
    for (std::size_t k = 0; k < free.size(); ++k) {
      if (free[k] != Param::kX0 && free[k] != Param::kY0) continue;
      const int c = free[k] == Param::kX0 ? 0 : 1;
      for (std::size_t i = 0; i < model.size(); ++i) jacobian[k][i] = dx[i] * inv[0][c] + dy[i] * inv[1][c];
    }
  }
  const double ab = p[index(Param::kBulgeA)], ad = p[index(Param::kDiscA)];
  const auto& bulge = component_stamps_[0];
  const auto& disc = component_stamps_[1];
  for (std::size_t i = 0; i < model.size(); ++i) model[i] = ab * bulge[i] + ad * disc[i];
  for (std::size_t k = 0; k < free.size(); ++k) {
    if (free[k] == Param::kBulgeA) std::copy(bulge.begin(), bulge.end(), jacobian[k]);
    if (free[k] == Param::kDiscA) std::copy(disc.begin(), disc.end(), jacobian[k]);
  }
  return RenderStatus::kOk;
}

}  // namespace stampede
