// The simulator's renderer: exact pixel integrals of Sérsic components convolved with an analytic
// PSF, drawn in Fourier space (the method of GalSim's FFT drawing, written from the maths).
//
// A pixel value is the sample at the pixel centre of  galaxy (x) PSF (x) pixel top-hat. Its
// transform, F_gal(k) F_psf(k) sinc(kx/2) sinc(ky/2), is known without sampling any profile: each
// Sérsic transform comes from a table (n = 1 in closed form), a shear maps k -> S k, a centre is a
// phase. Sampling at the pixel pitch aliases it; the aliases are summed explicitly out to where
// the PSF transform falls below 1e-12, and one inverse FFT of an N x N grid gives the samples.
// The only approximations are the tables (~1e-9 of the flux), the alias cut, and the period N of
// the inverse transform, chosen so that the profile's light beyond N - stamp pixels is below 1e-6
// of its half-light surface brightness.
//
// Layout: real images row-major, x fastest; stamp pixel (0, 0) is sample 0 of the grid.
#pragma once

#include <complex>
#include <cstdint>
#include <map>
#include <span>
#include <vector>

#include "engine/model/psf_model.hpp"
#include "engine/common/fftw_support.hpp"
#include "kernels/fourier_profiles.hpp"

namespace stampede {

// One Sérsic component: flux, half-light radius (pixels; circularised sqrt(ab)), reduced-shear
// ellipticity, centre in stamp pixel coordinates (0-based, pixel centres at integers).
struct SimComponent {
  double sersic_n = 1.0;
  double flux = 1.0;
  double half_light_radius = 1.0;
  double e1 = 0.0, e2 = 0.0;
  double x = 0.0, y = 0.0;
};

// Per-thread scratch: inverse-FFT plans and buffers by grid size.
class SimWorkspace {
 public:
  SimWorkspace() = default;
  SimWorkspace(const SimWorkspace&) = delete;
  SimWorkspace& operator=(const SimWorkspace&) = delete;
  ~SimWorkspace();

 private:
  friend class SimRenderer;
  struct Grid {
    void* plan = nullptr;  // fftw_plan, c2r n x n
    AlignedBuffer spectrum, image;
  };
  Grid& grid(int n);
  std::map<int, Grid> grids_;
  // Per-component constants hoisted out of the frequency loop, and its separable factors per axis
  // and alias: pixel sincs and, per component, phases exp(-i k x); kept here so a steady-state
  // render allocates nothing.
  struct Component {
    double s[3];
    double flux, hlr;
    const kernels::LogTable* table;  // looked up once, not per frequency
  };
  std::vector<Component> components_;
  std::vector<double> sinc_x_, sinc_y_;
  std::vector<std::complex<double>> phase_x_, phase_y_;
  // A galaxy draw's PSF terms on an n x n grid: the PSF transform times the pixel response at each
  // (kx, ky) the alias sum keeps, in the sum's order. They depend on the renderer and n alone, so
  // a thread drawing many galaxies computes them once per grid size instead of a Moffat table
  // lookup (a log and a 6-point interpolation) per term and draw. Values are bitwise those the
  // draw computed in place.
  struct PsfTerms {
    std::vector<double> psf;                   // per term: PSF x pixel response
    std::vector<std::uint32_t> ix, iy;         // per term: index into k_x, k_y (j * aliases + m + m_max)
    std::vector<std::uint32_t> end;            // per frequency jy * (n/2 + 1) + jx: one past its last term
    std::vector<double> k_x, k_y;              // per axis index: the frequency with its alias
  };
  std::map<int, PsfTerms> psf_terms_;
  std::uint64_t psf_terms_renderer_ = 0;  // SimRenderer::id_ of the renderer that made psf_terms_
};

// A Gaussian PSF, drawn by the simulator alone (the fitting renderers take PsfModel's kinds; the
// metadetection shear test's cells use a Gaussian). FWHM in pixels; reduced-shear ellipticity.
struct SimGaussianPsf {
  double fwhm = 0;
  double e1 = 0, e2 = 0;
  bool IsValid(std::string* why) const;
};

class SimRenderer {
 public:
  struct Options {
    // Sérsic indices to tabulate (n = 1 needs no table).
    std::vector<double> sersic_indices = {1.0, 4.0};
    // Largest half-light radius (pixels) and |e| to be drawn: they set the table's range.
    double max_half_light_radius = 10.0;
    double max_e = 0.95;
    bool IsValid(std::string* why) const;
  };

  // Throws std::invalid_argument for an image PSF, an obscured Airy disc, or invalid options.
  SimRenderer(const PsfModel& psf, const Options& options);
  // The same with a Gaussian PSF: its transform exp(-k^2 sigma^2 / 2) through the PSF's shear.
  SimRenderer(const SimGaussianPsf& psf, const Options& options);

  // size x size pixel integrals (flux per pixel) of the sum of `components` convolved with the PSF.
  // Components must use one of the tabulated indices.
  void render(std::span<const SimComponent> components, int size, std::span<double> out,
              SimWorkspace& workspace) const;
  // The PSF alone at sample pitch `step` (pixels), centred at (cx, cy) in sample coordinates:
  // with_pixel: pixel integrals (step must be 1); otherwise surface brightness x step^2.
  void render_psf(int size, double step, double cx, double cy, bool with_pixel, std::span<double> out,
                  SimWorkspace& workspace) const;
  // FWHM (pixels) of the round, centred components convolved with the round PSF, without the
  // pixel: the GREAT08 size Rgp is this over the PSF's own FWHM (fwhm of no components).
  double round_fwhm(std::span<const SimComponent> components) const;
  // Largest |k| (radians / pixel) at which the round PSF transform exceeds 1e-12.
  double psf_k_limit() const { return k_limit_; }
  // Radius (pixels, along the PSF's major axis) beyond which its surface brightness is below 1e-7
  // of its peak (an Airy disc: 1e-6 of its r^-3 envelope): how far a drawn profile spreads.
  double psf_tail_radius() const { return psf_tail_radius_; }

 private:
  double psf_transform(double kx, double ky) const;  // sheared
  double psf_round_transform(double k) const;
  // The Sérsic transform at q = k r_e from table (null: n = 1, in closed form).
  static double sersic_transform(const kernels::LogTable* table, double q);
  // The table for index n (null for n = 1); throws when n was not tabulated.
  const kernels::LogTable* table_for(double n) const;
  void build_sersic_tables(const Options& options);  // after the PSF's k_limit_ and stretch are set
  void set_gaussian(const SimGaussianPsf& psf);       // the Gaussian PSF's constants
  void draw(std::span<const SimComponent> components, bool with_psf_only, int size, double step, double cx,
            double cy, bool with_pixel, double tail_radius, std::span<double> out, SimWorkspace& ws) const;
  // ws's PSF terms of a galaxy draw on an n x n grid (unit step, pixel response), made when missing.
  const SimWorkspace::PsfTerms& galaxy_psf_terms(int n, SimWorkspace& ws) const;
  friend class RoundFwhmSolver;

  PsfModel psf_;
  double psf_alpha_ = 1.0;        // Moffat alpha, or lambda / D for Airy
  double gaussian_sigma_ = 0.0;   // > 0: the Gaussian PSF (psf_ is then unused)
  double psf_shear_[3] = {1, 0, 1};  // symmetric S: k -> (s00 kx + s01 ky, s01 kx + s11 ky)
  double psf_stretch_ = 1.0;      // largest |S^-1 k| / |k|
  double k_limit_ = 0.0;
  double psf_tail_radius_ = 0.0;
  kernels::LogTable moffat_table_;
  std::vector<std::pair<double, kernels::LogTable>> sersic_tables_;
  std::uint64_t id_ = 0;  // unique per constructed renderer: names it to a workspace's PSF terms
};

// SimRenderer::round_fwhm for a caller that solves for many profiles of one renderer (the GREAT08
// simulator finds each galaxy's radius by root finding on it, ~15 solves a galaxy). Each solve
// sums the quadrature's J0(k_i r) and J1(k_i r) at the radii it visits; the first of them (r = 0,
// the bracket's doublings 2^j / 4 and the first Newton point, the bracket's middle) are the same
// for every profile, so they are computed once here. Results are bitwise round_fwhm's.
// Immutable after construction: one solver may serve every thread. Holds a reference to renderer.
class RoundFwhmSolver {
 public:
  // bracket_tables: precompute the Bessel values above (~60,000 J0/J1 evaluations); without
  // them a solver is as cheap to build as one solve.
  RoundFwhmSolver(const SimRenderer& renderer, bool bracket_tables);
  double operator()(std::span<const SimComponent> components) const;

 private:
  static constexpr int kTabulatedDoublings = 8;  // brackets up to r = 32 px: every GREAT08 size
  const SimRenderer& renderer_;
  std::vector<double> nodes_, weights_;  // k_i and w_i h k_i of the Gauss-Legendre panels
  // Per doubling j: J0(k_i 2^j / 4); J0 and J1 at the bracket [2^(j-1) / 4, 2^j / 4]'s middle.
  std::vector<std::vector<double>> j0_doubling_, j0_middle_, j1_middle_;
};

// S such that a profile sheared by (e1, e2) has transform F(S k); det S = 1.
void shear_matrix(double e1, double e2, double s[3]);

}  // namespace stampede
