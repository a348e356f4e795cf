// The exact renderer's Fourier-space loop: the half-spectrum of Sérsic components convolved with a
// PSF and the pixel box, and of their derivatives, summed over a precomputed term list.
//
// On an N x N periodic grid at data resolution the DFT of the pixel values is the alias sum
//   M(k) = sum_n G(k + 2 pi n) PPi(k + 2 pi n),
// G the galaxy's transform, PPi the PSF's transform times the pixel sinc. Per component
//   G_c(k) = flux_c F_c(w_c(k)) e^{-i k.x0},  w_c(k) = k^T W_c k = (r_c |A_c^T k|)^2,
// F_c the unit-flux Sérsic transform as a function of w = q^2 (q = k r_e), W_c the quadratic form
// of the linear map (the inverse of the real-space form u(dx, dy)).
//
// Layout: spectra are split (real and imaginary parts in separate arrays), n rows of `row_stride`
// (a multiple of kKBlock, >= n/2 + 1) complex values; column jx of row jy is the r2c half-spectrum
// index (jy, jx), columns >= n/2 + 1 are padding (written, never read by the inverse FFT). The term
// list is grouped by spectrum block (one row, kKBlock consecutive columns): each block has a list
// of alias entries, each entry kKBlock PPi values. The loop writes every block once (no clearing,
// no read-modify-write), with all its aliases summed in registers.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "kernels/aligned_vector.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/isa.hpp"

namespace stampede::kernels {

inline constexpr int kKBlock = 8;  // spectrum columns per block: one AVX-512 vector, two AVX2

// A unit-flux Sérsic transform F as a function of w = q^2, tabulated for the term loop without a
// logarithm: w's own exponent and leading mantissa bits index the interval (kSubdivisions equal
// intervals per octave of w), and its remaining mantissa bits are the offset u in [0, 1) within
// it. Each interval holds a degree-5 polynomial in u (Chebyshev interpolation of LogTable's
// six-point Lagrange interpolant in log q over the same nodes, so both agree to ~1e-12 of F(0)),
// its six coefficients on one 64-byte line: the loop gathers them from one line per lane and gets
// the interpolant's own derivative dF/dw = P'(u) kSubdivisions 2^-octave. Below w_lo: 1 - c2 w;
// from w_hi: the power-law tail through LogTable's last two nodes, from the table's last value.
class SersicKTable {
 public:
  static constexpr int kCoefficients = 6;
  static constexpr int kStride = 8;  // doubles per interval: the coefficients, padded to a cache line
  static constexpr int kSubdivisionBits = 4;
  static constexpr int kSubdivisions = 1 << kSubdivisionBits;  // intervals per octave of w
  static constexpr int kIndexShift = 52 - kSubdivisionBits;    // bits(w) >> shift = octave and interval
  SersicKTable() = default;
  SersicKTable(const LogGrid& grid, const std::vector<double>& values);

  // F and dF/dw at w = q^2 (scalar reference of what the kernels compute).
  void evaluate(double w, double* value, double* slope_w) const;
  double q_max() const { return q_max_; }

  // For the kernels: interval i = (bits(w) >> kIndexShift) - index_base, coefficient j at
  // coefficients[i * kStride + j].
  std::int64_t index_base = 0;
  int intervals = 0;
  double w_lo = 0, c2 = 0;                          // below w_lo: 1 - c2 w
  double w_hi = 0, w_last = 0;                      // the table covers [w_lo, w_hi); w_last its largest w below w_hi
  double log_w_hi = 0, tail_value = 0, tail_slope = 0;  // from w_hi: tail_value (w / w_hi)^(tail_slope / 2)
  AlignedVector<double> coefficients;

 private:
  double q_max_ = 0;
};

// One component's transform parameters for a render (all in pixel and radian units).
struct KSpaceComponent {
  const SersicKTable* table = nullptr;  // null: the exponential (n = 1) in closed form
  double wxx = 0, wxy = 0, wyy = 0;     // w = wxx kx^2 + 2 wxy kx ky + wyy ky^2
  double e1xx = 0, e1xy = 0, e1yy = 0;  // dw/de1 as the same kind of form
  double e2xx = 0, e2xy = 0, e2yy = 0;  // dw/de2
  double flux = 0;                      // amplitude * flux per unit amplitude
  double flux_per_amplitude = 0;        // the amplitude column's scale
};

// Everything the loop needs beyond the terms, per render. The phase e^{-i k.x0} of a term at
// k = k0 + 2 pi m (k0 its spectrum bin's frequency, m its alias) factors into the bin's
// e^{-i k0.x0}, applied once per bin after the alias sum, and the alias's e^{-i 2 pi m.x0}, one
// constant per alias: so a term costs real products and one complex multiply-add per image.
struct KSpaceModel {
  KSpaceComponent bulge, disc;
  // d ln(r_e) / d(radius parameter): both radii scale with the disc radius, so w scales as its
  // square and the flux too: d G / d r = dlnr [2 (flux F + flux w dF/dw)] summed over components.
  double dlnr = 0;
  // e^{-i kx0 x0} at the bin columns jx (row_stride values), e^{-i ky0 y0} at the rows jy (n values).
  const double* bin_phase_x_re = nullptr;
  const double* bin_phase_x_im = nullptr;
  const double* bin_phase_y_re = nullptr;
  const double* bin_phase_y_im = nullptr;
  // e^{-i 2 pi m.x0} per alias pair (KSpaceTerms::entry_alias indexes it).
  const double* alias_phase_re = nullptr;
  const double* alias_phase_im = nullptr;
};

// The term list of one PSF on one grid; immutable once built, shared read-only.
struct KSpaceTerms {
  int n = 0;           // period (grid side), pixels
  int row_stride = 0;  // padded half-spectrum row length, a multiple of kKBlock
  // Distinct wavevector components: kx_values[ix], ky_values[iy] (radians per pixel), in alias
  // groups: kx_values[a * row_stride + jx] = 2 pi (a - alias_max) + 2 pi jx / n, and
  // ky_values[a * n + jy] likewise with jy's signed frequency.
  int alias_max = 0;  // aliases m = -alias_max .. alias_max per axis
  AlignedVector<double> kx_values, ky_values;
  // Spectrum block b (row b / (row_stride / kKBlock)) holds entries [block_begin[b], block_begin[b+1]).
  std::vector<std::int32_t> block_begin;
  // Per entry: index of its first lane's kx in kx_values (its lanes are consecutive) and its ky's,
  // and its alias pair ax * aliases() + ay (a = m + alias_max).
  std::vector<std::int32_t> entry_ix, entry_iy, entry_alias;
  // Per entry, kKBlock lanes: PPi / n^2 (FFTW's normalisation folded in). Real: the PSFs the term
  // list is built for (Moffat, Airy) are centrosymmetric about their centre.
  AlignedVector<double> ppi;

  int aliases() const { return 2 * alias_max + 1; }
  int blocks() const { return static_cast<int>(block_begin.size()) - 1; }
  long long entries() const { return static_cast<long long>(entry_ix.size()); }
};

// Output spectra (split complex, n * row_stride values each). Model-only: model. With the
// Jacobian: bulge and disc (per unit amplitude), then d/dx0, d/dy0, d/de1, d/de2, d/dradius.
enum KSpaceImage : int { kKBulge = 0, kKDisc, kKX0, kKY0, kKE1, kKE2, kKRadius, kNumKSpaceImages };
struct KSpaceSpectra {
  std::array<double*, kNumKSpaceImages> re{}, im{};
};

struct KSpaceKernels {
  const char* name = "";
  int lanes = 1;
  // re[0], im[0] = the model's half-spectrum.
  void (*accumulate_model)(const KSpaceTerms& terms, const KSpaceModel& model, const KSpaceSpectra& out) = nullptr;
  // re[kKBulge], re[kKDisc] (and im): the two components per unit amplitude.
  void (*accumulate_components)(const KSpaceTerms& terms, const KSpaceModel& model, const KSpaceSpectra& out) = nullptr;
  // All kNumKSpaceImages spectra.
  void (*accumulate_jacobian)(const KSpaceTerms& terms, const KSpaceModel& model, const KSpaceSpectra& out) = nullptr;
};

// The kernels for a set; nullptr when it was not compiled in or this CPU lacks it.
const KSpaceKernels* kspace_kernels_for(Isa isa);
// kspace_kernels_for(isa), or the scalar kernels when that set is unavailable.
const KSpaceKernels& kspace_kernels(Isa isa = Isa::kBest);

}  // namespace stampede::kernels
