// The option registry behind run_config.hpp and the ini / --set readers built on it.
#include "io/run_config.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <system_error>
#include <tuple>

#include "engine/common/quoted_value.hpp"
#include "engine/model/psf_model.hpp"
#include "io/text_lines.hpp"

namespace stampede::io {
namespace {

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n\f\v");
  if (first == std::string_view::npos) return "";
  const auto last = s.find_last_not_of(" \t\r\n\f\v");
  return std::string(s.substr(first, last - first + 1));
}

// psf_input's value for a catalogue source of Moffat PSFs (psf_kind_name names the kinds).
constexpr const char* kMoffatCatalog = "moffat_catalog";

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// from_chars rejects a leading '+', a legitimate way to write a positive number.
std::string_view strip_plus(std::string_view s) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '+' && s[1] != '-') s.remove_prefix(1);
  return s;
}

// --- Value text: parsers return "" on success or why not; printers give the canonical form. ---

template <class Int>
std::string parse_integer(std::string_view text, Int* out) {
  if (text.empty()) return "empty value, expected an integer";
  const std::string_view s = strip_plus(text);
  Int v{};
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) return "out of range for an integer";
  if (ec != std::errc() || ptr != s.data() + s.size()) return "expected an integer";
  *out = v;
  return "";
}

enum class DoubleKind {
  kFinite,       // a finite number
  kStart,        // finite or `auto` (NaN: from the image moments)
  kBound,        // finite, inf, -inf or `auto` (NaN: derived from the stamp)
};

std::string parse_double(std::string_view text, DoubleKind kind, double* out) {
  if (text.empty()) return "empty value, expected a number";
  if (kind != DoubleKind::kFinite && lower(text) == "auto") {
    *out = NAN;
    return "";
  }
  const std::string_view s = strip_plus(text);
  double v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) return "out of range for a double";
  if (ec != std::errc() || ptr != s.data() + s.size()) return "expected a number";
  // "nan" parses, but NaN is spelled `auto` where it means something, and is an error elsewhere.
  if (std::isnan(v)) return kind == DoubleKind::kFinite ? "expected a finite number" : "expected a number or 'auto'";
  if (std::isinf(v) && kind != DoubleKind::kBound) return "must be finite";
  *out = v;
  return "";
}

// Shortest text that parses back to exactly v (std::to_chars' guarantee), so header values read
// "0.95" rather than %.17g's "0.94999999999999996" while still round-tripping bit for bit.
std::string format_double(double v) {
  if (std::isnan(v)) return "auto";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  return ec == std::errc() ? std::string(buf, ptr) : std::string("?");
}

std::string parse_bool(std::string_view text, bool* out) {
  const std::string s = lower(text);
  if (s == "true" || s == "yes" || s == "1") {
    *out = true;
  } else if (s == "false" || s == "no" || s == "0") {
    *out = false;
  } else {
    return "expected true/false, yes/no or 1/0";
  }
  return "";
}

std::string format_bool(bool v) { return v ? "true" : "false"; }

// save_images: ids separated by commas, spaces around them allowed; "" = none.
std::string parse_id_list(std::string_view text, std::vector<std::int64_t>* ids) {
  ids->clear();
  if (trim(text).empty()) return "";
  std::size_t pos = 0;
  while (true) {
    const std::size_t comma = text.find(',', pos);
    const std::string item = trim(text.substr(pos, comma == std::string_view::npos ? text.npos : comma - pos));
    std::int64_t id = 0;
    if (item.empty() || !parse_integer(item, &id).empty())
      return "expected comma-separated integer object ids, got " + quoted_value(item);
    ids->push_back(id);
    if (comma == std::string_view::npos) return "";
    pos = comma + 1;
  }
}

std::string format_id_list(const std::vector<std::int64_t>& ids) {
  std::string out;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (i) out += ',';
    out += std::to_string(ids[i]);  // appended apart: GCC 12 warns falsely (-Wrestrict) on "," + string
  }
  return out;
}

// --- The registry ---------------------------------------------------------------------------

struct Entry {
  std::string name;
  std::string help;
  std::string section;  // heading in the template
  std::function<std::string(const RunConfig&)> get;
  std::function<std::string(RunConfig&, const std::string&)> set;  // "" on success, else why not
  HeaderValueType type = HeaderValueType::kText;
};

// `access` is a generic lambda `[](auto& c) -> auto& { return c.field; }`, so one accessor serves
// both the const getter and the setter.
template <class Access>
Entry int_entry(const char* section, const char* name, const char* help, Access access) {
  return {name, help, section, [access](const RunConfig& c) { return std::to_string(access(c)); },
          [access](RunConfig& c, const std::string& v) {
            int x = 0;
            std::string why = parse_integer(v, &x);
            if (why.empty()) access(c) = x;
            return why;
          },
          HeaderValueType::kInteger};
}

template <class Access>
Entry double_entry(const char* section, std::string name, std::string help, DoubleKind kind, Access access) {
  return {std::move(name), std::move(help), section, [access](const RunConfig& c) { return format_double(access(c)); },
          [access, kind](RunConfig& c, const std::string& v) {
            double x = 0;
            std::string why = parse_double(v, kind, &x);
            if (why.empty()) access(c) = x;
            return why;
          },
          HeaderValueType::kReal};
}

template <class Access>
Entry bool_entry(const char* section, std::string name, std::string help, Access access) {
  return {std::move(name), std::move(help), section, [access](const RunConfig& c) { return format_bool(access(c)); },
          [access](RunConfig& c, const std::string& v) {
            bool x = false;
            std::string why = parse_bool(v, &x);
            if (why.empty()) access(c) = x;
            return why;
          }};
}

template <class Access>
Entry string_entry(const char* section, const char* name, const char* help, Access access) {
  return {name, help, section, [access](const RunConfig& c) { return std::string(access(c)); },
          [access](RunConfig& c, const std::string& v) {
            access(c) = v;
            return std::string();
          }};
}

// What each model parameter is, for the help of its four keys (Param order).
constexpr const char* kParamMeaning[kNumParams] = {
    "centroid x, data pixels (0-based, pixel centres at integers)",
    "centroid y, data pixels",
    "ellipticity (a-b)/(a+b) along x",
    "ellipticity along y = x",
    "disc half-light radius (circularised), pixels",
    "bulge central intensity, flux / pixel^2",
    "disc central intensity, flux / pixel^2",
    "bulge / disc half-light radius",
    "Sersic index of the bulge",
    "Sersic index of the disc",
    "|e_bulge| - |e_disc|",
    "bulge - disc position angle, radians",
};

void add_parameter_entries(std::vector<Entry>* entries) {
  const char* section = "Model parameters (start = the fixed value when not free)";
  for (int k = 0; k < kNumParams; ++k) {
    const Param p = static_cast<Param>(k);
    const std::string n(param_name(p));
    // Moments give a start for the centroid, shape, size and amplitudes only.
    const bool from_moments = index(p) <= index(Param::kDiscA);
    const bool centroid = p == Param::kX0 || p == Param::kY0;
    auto spec = [k](auto& c) -> auto& { return c.fitter.params.spec[k]; };
    entries->push_back(double_entry(
        section, n + "_start",
        n + ": " + kParamMeaning[k] + "; start value, or the value held when " + n + "_free = false" +
            (from_moments ? "; auto = from the image moments" : ""),
        DoubleKind::kStart, [spec](auto& c) -> auto& { return spec(c).start; }));
    const std::string unbounded = centroid ? "; auto = the stamp's edge" : "; -inf = none";
    entries->push_back(double_entry(section, n + "_min", n + ": lower bound" + unbounded, DoubleKind::kBound,
                                    [spec](auto& c) -> auto& { return spec(c).lower; }));
    entries->push_back(double_entry(section, n + "_max",
                                    n + ": upper bound" + (centroid ? "; auto = the stamp's edge" : "; inf = none"),
                                    DoubleKind::kBound, [spec](auto& c) -> auto& { return spec(c).upper; }));
    entries->push_back(bool_entry(
        section, n + "_free",
        is_freeable(p) ? "fit " + n + " (true) or hold it at " + n + "_start (false)"
                       : "must be false: the renderer has no derivative image for " + n + " yet",
        [spec](auto& c) -> auto& { return spec(c).free; }));
  }
}

std::vector<Entry> make_registry() {
  std::vector<Entry> r;
  const char* render = "Rendering (paper section 4.1)";
  r.push_back({"renderer",
               std::string("the fitter's renderer: ") + renderer_kind_names() +
                   " (auto, the default: exact wherever it takes the PSF, i.e. Moffat beta > 2 and pixel-integrated "
                   "image PSFs at the data's sampling, MEDS; upsampled for the Airy disc, Moffat beta <= 2 and "
                   "oversampled or point-sampled image PSFs, said on stderr; exact: pixel values from the continuous "
                   "transform of galaxy x PSF x pixel, at data resolution; upsampled: the paper's sub-pixel grid, FFT "
                   "convolution with the PSF, block average, for im3shape comparisons)",
               render, [](const RunConfig& c) { return std::string(renderer_kind_name(c.fitter.renderer)); },
               [](RunConfig& c, const std::string& v) {
                 if (parse_renderer_kind(v, &c.fitter.renderer)) return std::string();
                 return std::string("expected ") + renderer_kind_names();
               }});
  r.push_back(int_entry(render, "stamp_size",
                        "data pixels per stamp side; when not set, the input file's STAMPSZ header",
                        [](auto& c) -> auto& { return c.fitter.render.stamp_size; }));
  r.push_back(int_entry(render, "upsampling", "U1: model sub-pixels per data pixel, per side",
                        [](auto& c) -> auto& { return c.fitter.render.upsampling; }));
  r.push_back(int_entry(render, "n_central_pixels_to_upsample",
                        "N_u: side of the central block of sub-pixels integrated finely",
                        [](auto& c) -> auto& { return c.fitter.render.n_central_pixels_to_upsample; }));
  r.push_back(int_entry(render, "n_central_pixel_upsampling",
                        "U2: integration points per sub-pixel side in that block",
                        [](auto& c) -> auto& { return c.fitter.render.n_central_pixel_upsampling; }));
  r.push_back(int_entry(render, "padding",
                        "data pixels of model grid added around the stamp (light scattered in from outside, "
                        "no FFT wrap-around)",
                        [](auto& c) -> auto& { return c.fitter.render.padding; }));
  r.push_back({"simd",
               "instruction set of the profile kernels: best (the widest this CPU supports), scalar, sse4.2, "
               "avx2 or avx512; sets agree to a few ulp, so name one for bitwise-identical fits across machines",
               render, [](const RunConfig& c) { return std::string(kernels::isa_name(c.fitter.render.simd)); },
               [](RunConfig& c, const std::string& v) {
                 if (kernels::parse_isa(v.c_str(), &c.fitter.render.simd)) return std::string();
                 return std::string("expected best, scalar, sse4.2, avx2 or avx512");
               }});
  r.push_back(double_entry(render, "exact_psf_tolerance",
                           "renderer = exact: PSF x pixel transform terms at most this are dropped (1e-7: 4e-8 of "
                           "the peak)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.render.exact.psf_tolerance; }));
  r.push_back(int_entry(render, "exact_period",
                        "renderer = exact: period of its Fourier grid, pixels; 0 = the rule (stamp_size + 57, "
                        "FFT-friendly)",
                        [](auto& c) -> auto& { return c.fitter.render.exact.period; }));
  r.push_back(int_entry(render, "exact_wrap_rings",
                        "renderer = exact: rings of periodic copies whose light is subtracted (at most); 0 = none",
                        [](auto& c) -> auto& { return c.fitter.render.exact.wrap_rings; }));
  r.push_back(int_entry(render, "exact_wrap_nodes",
                        "renderer = exact: Chebyshev nodes per stamp side for the copies' light",
                        [](auto& c) -> auto& { return c.fitter.render.exact.wrap_nodes; }));
  r.push_back(bool_entry(render, "exact_surrogate",
                         "renderer = exact: iterate first on a cheaper surrogate of the same model (a smaller "
                         "period, looser terms), then exactly until the stopping rules hold; false: every "
                         "iteration exact",
                         [](auto& c) -> auto& { return c.fitter.render.exact.surrogate; }));
  r.push_back(int_entry(render, "surrogate_period",
                        "exact_surrogate: period of the surrogate's Fourier grid; 0 = the rule (stamp_size + 25, "
                        "FFT-friendly)",
                        [](auto& c) -> auto& { return c.fitter.render.exact.surrogate_period; }));
  r.push_back(double_entry(render, "surrogate_psf_tolerance", "exact_surrogate: the surrogate's exact_psf_tolerance",
                           DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.fitter.render.exact.surrogate_psf_tolerance; }));
  r.push_back(int_entry(render, "surrogate_wrap_rings", "exact_surrogate: the surrogate's exact_wrap_rings",
                        [](auto& c) -> auto& { return c.fitter.render.exact.surrogate_wrap_rings; }));
  r.push_back(int_entry(render, "surrogate_wrap_nodes", "exact_surrogate: the surrogate's exact_wrap_nodes",
                        [](auto& c) -> auto& { return c.fitter.render.exact.surrogate_wrap_nodes; }));
  r.push_back(double_entry(render, "surrogate_eps4",
                           "exact_surrogate: levmar_eps4's rule for the surrogate iterations (the exact ones that "
                           "follow use levmar_eps4)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.surrogate_eps4; }));
  r.push_back(double_entry(render, "noise_sigma",
                           "per-pixel noise sigma when no weight map is given; 0 = unweighted (noise-free data)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.noise_sigma; }));

  const char* lm = "Levenberg-Marquardt stopping rules (paper appendix B)";
  r.push_back(double_entry(lm, "levmar_eps1", "stop when max |J^T W (d - m)| <= eps1; 0 = off", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.fitter.lm.eps1; }));
  r.push_back(double_entry(lm, "levmar_eps2",
                           "stop when |dp|^2 <= eps2^2 |p|^2; 0 = off (scale-sensitive: |p| is dominated by bulge_A)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.lm.eps2; }));
  r.push_back(double_entry(lm, "levmar_eps3", "stop when chi2 <= eps3; 0 = off", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.fitter.lm.eps3; }));
  r.push_back(double_entry(lm, "levmar_eps4",
                           "stop when an accepted step changes chi2 relatively by < eps4 / n_pixels and the "
                           "Gauss-Newton step predicts no more (or three such steps in a row); 0 = off",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.lm.eps4; }));
  r.push_back(double_entry(lm, "levmar_LM_INIT_MU", "initial damping, relative to diag(J^T W J)", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.fitter.lm.init_mu; }));
  r.push_back(int_entry(lm, "minimizer_max_iterations", "maximum Jacobian evaluations per stamp",
                        [](auto& c) -> auto& { return c.fitter.lm.max_iterations; }));
  r.push_back(bool_entry(lm, "project_amplitudes",
                         "true: solve bulge_A and disc_A linearly at every trial shape and iterate on the "
                         "shape alone (variable projection; the same optimum in fewer iterations, when both "
                         "are free and unbounded); false: iterate on all free parameters jointly (the paper's)",
                         [](auto& c) -> auto& { return c.fitter.project_amplitudes; }));

  const char* mcal = "Metacalibration (README, \"Metacalibration\")";
  r.push_back(bool_entry(mcal, "metacal",
                         "true: each object's shear response R from its own image (deconvolve the PSF, shear by "
                         "+-metacal_step, reconvolve with a round Moffat, five fits); the row's e is the noshear "
                         "image's and the table gains R11 R12 R21 R22 and the sheared fits",
                         [](auto& c) -> auto& { return c.metacal.enabled; }));
  r.push_back(double_entry(mcal, "metacal_step", "metacal: the applied shear delta, in (0, 0.1]", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.metacal.step; }));
  r.push_back(double_entry(mcal, "metacal_psf_dilation",
                           "metacal: reconvolution PSF FWHM over the PSF's; 0 = (1 + 2 metacal_step) sqrt((1 + |e|) "
                           "/ (1 - |e|)), the smallest wider than the sheared PSF in every direction",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.metacal.psf_dilation; }));
  r.push_back(bool_entry(mcal, "metacal_fixnoise",
                         "metacal: add a noise field rotated by 90 degrees through the same operations, so that "
                         "the images' noise is isotropic (doubles its variance)",
                         [](auto& c) -> auto& { return c.metacal.fixnoise; }));
  r.push_back({"metacal_seed", "metacal: seed of the fixnoise fields (each object's keyed by its id), in [0, 2^63)", mcal,
               [](const RunConfig& c) { return std::to_string(c.metacal.seed); },
               [](RunConfig& c, const std::string& v) {
                 std::int64_t seed = 0;
                 const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), seed);
                 if (ec != std::errc() || end != v.data() + v.size() || seed < 0)
                   return std::string("expected an integer in [0, 2^63)");
                 c.metacal.seed = static_cast<std::uint64_t>(seed);
                 return std::string();
               },
               HeaderValueType::kInteger});
  r.push_back({"metacal_model",
               "metacal: its estimator on the five images (the row's e is the noshear image's): wmom (default) fits "
               "nothing, the moments under a round Gaussian weight of metacal_weight_fwhm (as DES Y6); bd (the run's "
               "bulge + disc model), exp (the disc alone) or gauss (a Sersic n = 0.5 alone, as DES Y3) are fits; exp "
               "and gauss replace the amplitude and bulge_index settings",
               mcal,
               [](const RunConfig& c) {
                 switch (c.metacal.model) {
                   case MetacalModel::kExponential: return std::string("exp");
                   case MetacalModel::kGaussian: return std::string("gauss");
                   case MetacalModel::kWeightedMoments: return std::string("wmom");
                   default: return std::string("bd");
                 }
               },
               [](RunConfig& c, const std::string& v) {
                 const std::string l = lower(v);
                 if (l == "bd") c.metacal.model = MetacalModel::kBulgeDisc;
                 else if (l == "exp") c.metacal.model = MetacalModel::kExponential;
                 else if (l == "gauss") c.metacal.model = MetacalModel::kGaussian;
                 else if (l == "wmom") c.metacal.model = MetacalModel::kWeightedMoments;
                 else return std::string("expected bd, exp, gauss or wmom");
                 return std::string();
               }});
  r.push_back(double_entry(mcal, "metacal_weight_fwhm",
                           "metacal_model = wmom: FWHM of the moments' round Gaussian weight, in pixels (in the sky's "
                           "units, arcsec, for MEDS tiles); 0 = 2.5 x the reconvolution PSF's",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.metacal.weight_fwhm; }));

  const char* model = "Model reparameterisation (paper appendix A)";
  r.push_back(double_entry(model, "ellipticity_mirror", "|e| about which the ellipticity is mirrored, in (0, 1)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.model.ellipticity_mirror; }));
  r.push_back(double_entry(model, "radius_softening",
                           "radius R in sub-pixels below which the disc radius r is softened to (R + r^2/R)/2",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.fitter.model.radius_softening; }));

  add_parameter_entries(&r);

  const char* psf = "PSF";
  r.push_back({"psf_input",
               "moffat (psf_* keys), airy (airy_* keys), moffat_catalog (a Moffat per object from the "
               "catalog_psf_* columns) or image (psf_image)",
               psf, [](const RunConfig& c) { return psf_input_value(c); },
               [](RunConfig& c, const std::string& v) {
                 if (lower(v) == kMoffatCatalog) {
                   c.psf_kind = PsfKind::kMoffat;
                   c.psf_from_catalogue = true;
                 } else if (parse_psf_kind(v, &c.psf_kind)) {
                   c.psf_from_catalogue = false;
                 } else {
                   return std::string("expected moffat, airy, moffat_catalog or image");
                 }
                 return std::string();
               }});
  r.push_back(double_entry(psf, "psf_beta", "Moffat beta, > 1", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.moffat.beta; }));
  r.push_back(double_entry(psf, "psf_fwhm", "Moffat FWHM, pixels", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.moffat.fwhm; }));
  r.push_back(double_entry(psf, "psf_e1", "Moffat ellipticity along x (reduced-shear convention)", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.moffat.e1; }));
  r.push_back(double_entry(psf, "psf_e2", "Moffat ellipticity along y = x", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.moffat.e2; }));
  r.push_back(double_entry(psf, "psf_truncation",
                           "Moffat truncation radius, pixels (also for moffat_catalog); 0 = none", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.moffat.truncation; }));
  r.push_back(double_entry(psf, "airy_lambda_over_d", "Airy lambda / D, pixels", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.airy.lambda_over_d; }));
  r.push_back(double_entry(psf, "airy_obscuration", "Airy central obscuration, in [0, 1)", DoubleKind::kFinite,
                           [](auto& c) -> auto& { return c.airy.obscuration; }));
  r.push_back(string_entry(psf, "psf_image", "FITS image of the PSF (psf_input = image)",
                           [](auto& c) -> auto& { return c.psf_image; }));
  r.push_back(int_entry(psf, "psf_upsampling", "samples of psf_image per data pixel, per side",
                        [](auto& c) -> auto& { return c.psf_upsampling; }));
  r.push_back(bool_entry(psf, "psf_pixel_integrated",
                         "true: psf_image samples are pixel integrals (their top-hat is divided out); "
                         "false: point samples",
                         [](auto& c) -> auto& { return c.psf_pixel_integrated; }));

  const char* run = "Run";
  r.push_back(int_entry(run, "batch_size", "stamps per batch (one task of the pipeline), in [1, 100000]",
                        [](auto& c) -> auto& { return c.batch_size; }));
  r.push_back(string_entry(run, "fft_wisdom", "FFTW wisdom cache file; empty = none",
                           [](auto& c) -> auto& { return c.fft_wisdom; }));

  const char* cat = "Catalogue input: column names";
  r.push_back(string_entry(cat, "catalog_id_column", "object id",
                           [](auto& c) -> auto& { return c.catalog_id_column; }));
  r.push_back(string_entry(cat, "catalog_x_column", "object x position, FITS 1-based pixels",
                           [](auto& c) -> auto& { return c.catalog_x_column; }));
  r.push_back(string_entry(cat, "catalog_y_column", "object y position, FITS 1-based pixels",
                           [](auto& c) -> auto& { return c.catalog_y_column; }));
  r.push_back(string_entry(cat, "catalog_psf_beta_column", "Moffat beta (psf_input = moffat_catalog)",
                           [](auto& c) -> auto& { return c.catalog_psf_beta_column; }));
  r.push_back(string_entry(cat, "catalog_psf_fwhm_column", "Moffat FWHM, pixels (psf_input = moffat_catalog)",
                           [](auto& c) -> auto& { return c.catalog_psf_fwhm_column; }));
  r.push_back(string_entry(cat, "catalog_psf_e1_column", "Moffat e1 (psf_input = moffat_catalog)",
                           [](auto& c) -> auto& { return c.catalog_psf_e1_column; }));
  r.push_back(string_entry(cat, "catalog_psf_e2_column", "Moffat e2 (psf_input = moffat_catalog)",
                           [](auto& c) -> auto& { return c.catalog_psf_e2_column; }));

  const char* meds = "Survey input (stampede fit --meds)";
  r.push_back({"meds_model", "bd (co-elliptical bulge + disc) or bord (a pure bulge and a pure disc each fitted, the "
               "better likelihood kept; column is_bulge)", meds,
               [](const RunConfig& c) { return std::string(c.meds.model == MedsModel::kBulgeDisc ? "bd" : "bord"); },
               [](RunConfig& c, const std::string& v) {
                 const std::string l = lower(v);
                 if (l == "bd") c.meds.model = MedsModel::kBulgeDisc;
                 else if (l == "bord") c.meds.model = MedsModel::kBulgeOrDisc;
                 else return std::string("expected bd or bord");
                 return std::string();
               }});
  r.push_back({"meds_psf",
               "each cutout's PSF: auto (the tile's psf cutouts if it has them, else PSFEx), psfex (image_info "
               "psf_path), cutouts (the psf HDU) or options (the run's psf_* keys in every cutout's pixels)",
               meds,
               [](const RunConfig& c) {
                 switch (c.meds.psf) {
                   case MedsPsfSource::kPsfex: return std::string("psfex");
                   case MedsPsfSource::kCutouts: return std::string("cutouts");
                   case MedsPsfSource::kOptions: return std::string("options");
                   default: return std::string("auto");
                 }
               },
               [](RunConfig& c, const std::string& v) {
                 const std::string l = lower(v);
                 if (l == "auto") c.meds.psf = MedsPsfSource::kAuto;
                 else if (l == "psfex") c.meds.psf = MedsPsfSource::kPsfex;
                 else if (l == "cutouts") c.meds.psf = MedsPsfSource::kCutouts;
                 else if (l == "options") c.meds.psf = MedsPsfSource::kOptions;
                 else return std::string("expected auto, psfex, cutouts or options");
                 return std::string();
               }});
  r.push_back(bool_entry(meds, "meds_fit_coadd", "true: fit cutout 0 (the coadd) alone; false: the single epochs jointly",
                         [](auto& c) -> auto& { return c.meds.fit_coadd; }));
  r.push_back({"meds_bmask_bits",
               "a pixel whose bmask has any of these bits set is masked (decimal or 0x hex; 0 = bmask ignored)", meds,
               [](const RunConfig& c) { return std::to_string(c.meds.bmask_bits); },
               [](RunConfig& c, const std::string& v) {
                 const bool hex = v.size() > 2 && v[0] == '0' && (v[1] == 'x' || v[1] == 'X');
                 std::uint64_t bits = 0;
                 const char* first = v.data() + (hex ? 2 : 0);
                 const auto [end, ec] = std::from_chars(first, v.data() + v.size(), bits, hex ? 16 : 10);
                 if (v.empty() || ec != std::errc() || end != v.data() + v.size() || bits > 0xffffffffu)
                   return std::string("expected an unsigned 32-bit integer (decimal or 0x hex)");
                 c.meds.bmask_bits = static_cast<std::uint32_t>(bits);
                 return std::string();
               },
               HeaderValueType::kInteger});
  r.push_back(bool_entry(meds, "meds_uberseg",
                         "mask every pixel whose nearest labelled seg pixel belongs to another object (needs seg_cutouts)",
                         [](auto& c) -> auto& { return c.meds.uberseg; }));
  r.push_back(double_entry(meds, "meds_min_unmasked_fraction",
                           "flag the row (too masked, not fitted) when the usable cutouts' unmasked pixels are a smaller "
                           "fraction, in [0, 1]",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.meds.min_unmasked_fraction; }));
  r.push_back(double_entry(meds, "meds_magzp_ref",
                           "zero point of the output fluxes: each cutout's data are 10^(0.4 (magzp - meds_magzp_ref)) "
                           "times the model",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.meds.magzp_ref; }));
  r.push_back(string_entry(meds, "meds_psf_dir",
                           "directory of image_info's relative psf_path (PSFEx files); empty = the tile's directory",
                           [](auto& c) -> auto& { return c.meds.psf_dir; }));

  r.push_back({"save_images", "comma-separated object ids whose model and residual images are saved; empty = none",
               "Output", [](const RunConfig& c) { return c.save_images; },
               [](RunConfig& c, const std::string& v) {
                 std::vector<std::int64_t> ids;
                 std::string why = parse_id_list(v, &ids);
                 if (why.empty()) c.save_images = format_id_list(ids);  // canonical: "3,17,42"
                 return why;
               }});
  return r;
}

// Built once, then immutable (a thread-safe local static, not a cache).
const std::vector<Entry>& registry() {
  static const std::vector<Entry> entries = make_registry();
  return entries;
}

const Entry* find_entry(const std::string& key) {
  for (const Entry& e : registry())
    if (e.name == key) return &e;
  return nullptr;
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

ConfigError unknown_option(const std::string& key) {
  std::string msg = "unknown option " + quoted_value(key);
  const Entry* best = nullptr;
  std::size_t best_d = 3;  // suggest only typos: at most two edits
  for (const Entry& e : registry()) {
    const std::size_t d = edit_distance(lower(key), lower(e.name));
    if (d < best_d) best = &e, best_d = d;
  }
  if (best) msg += " (did you mean '" + best->name + "'?)";
  return ConfigError(msg);
}

// Throws `why`, prefixed by the file and line that set KEY when it starts with a key from an ini
// file (engine messages read "KEY = VALUE: ..."); a --set value is on the user's command line.
[[noreturn]] void fail(const RunConfig& c, const std::string& why) {
  const auto end = std::find_if_not(why.begin(), why.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_';
  });
  const auto it = c.explicitly_set.find(std::string(why.begin(), end));
  if (it != c.explicitly_set.end() && !it->second.empty() && it->second != "--set")
    throw ConfigError(it->second + ": " + why);
  throw ConfigError(why);
}

}  // namespace

std::string psf_input_value(const RunConfig& config) {
  return config.psf_from_catalogue ? kMoffatCatalog : psf_kind_name(config.psf_kind);
}

const std::vector<OptionInfo>& run_config_options() {
  static const std::vector<OptionInfo> options = [] {
    const RunConfig defaults;
    std::vector<OptionInfo> out;
    for (const Entry& e : registry()) out.push_back({e.name, e.get(defaults), e.help, e.type});
    return out;
  }();
  return options;
}

void set_option(RunConfig& config, const std::string& key, const std::string& value) {
  const Entry* e = find_entry(key);
  if (!e) throw unknown_option(key);
  const std::string why = e->set(config, value);
  if (!why.empty()) throw ConfigError("option " + quoted_value(key) + " = " + quoted_value(value) + ": " + why);
  config.explicitly_set[key] = "";
}

std::string get_option(const RunConfig& config, const std::string& key) {
  const Entry* e = find_entry(key);
  if (!e) throw unknown_option(key);
  return e->get(config);
}

void load_ini(RunConfig& config, const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("cannot read config file '" + path + "'");
  RunConfig updated = config;  // all or nothing
  std::map<std::string, int> line_of;  // key -> line that set it, to reject repeats
  std::string line;
  for (int number = 1;; ++number) {
    const TextLine read = read_text_line(in, &line);
    if (read == TextLine::kEnd) break;
    const std::string where = path + ":" + std::to_string(number);
    if (read == TextLine::kTooLong)
      throw ConfigError(where + ": a line longer than " + std::to_string(kMaxTextLine) + " bytes: not a configuration file");
    if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);  // UTF-8 byte-order mark
    const std::string text = trim(std::string_view(line).substr(0, line.find('#')));
    if (text.empty() || (text.front() == '[' && text.back() == ']')) continue;
    const std::size_t eq = text.find('=');
    const std::string key = eq == std::string::npos ? "" : trim(std::string_view(text).substr(0, eq));
    if (key.empty()) throw ConfigError(where + ": expected 'key = value'");
    if (auto [it, fresh] = line_of.emplace(key, number); !fresh)
      throw ConfigError(where + ": option " + quoted_value(key) + " is set twice (first on line " + std::to_string(it->second) +
                        ")");
    try {
      set_option(updated, key, trim(std::string_view(text).substr(eq + 1)));
    } catch (const ConfigError& e) {
      throw ConfigError(where + ": " + e.what());
    }
    updated.explicitly_set[key] = where;
  }
  if (in.bad()) throw ConfigError("cannot read config file '" + path + "'");  // e.g. a directory
  config = std::move(updated);
}

void apply_set(RunConfig& config, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  const std::string key = eq == std::string::npos ? "" : trim(std::string_view(assignment).substr(0, eq));
  if (key.empty()) throw ConfigError("--set " + quoted_value(assignment) + ": expected key=value");
  try {
    set_option(config, key, trim(std::string_view(assignment).substr(eq + 1)));
  } catch (const ConfigError& e) {
    throw ConfigError("--set " + quoted_value(assignment) + ": " + e.what());
  }
  config.explicitly_set[key] = "--set";
}

void validate(const RunConfig& config) {
  std::string why;
  if (!config.fitter.IsValid(&why)) fail(config, why);
  // A NaN bound means "derived from the stamp", which the fitter does only for the centroid; any
  // other parameter would have no valid model at all.
  for (int k = 0; k < kNumParams; ++k) {
    const Param p = static_cast<Param>(k);
    if (p == Param::kX0 || p == Param::kY0) continue;
    const ParamSpec& s = config.fitter.params.spec[k];
    for (const auto& [suffix, value, none] :
         {std::tuple{"_min", s.lower, "-inf"}, std::tuple{"_max", s.upper, "inf"}}) {
      if (std::isnan(value))
        fail(config, std::string(param_name(p)) + suffix + " = auto: only x0 and y0 have automatic bounds; use " +
                         none + " for none");
    }
  }

  switch (config.psf_kind) {
    // A catalogue source replaces beta, fwhm, e1, e2 per object; the configured Moffat must still
    // be valid, as its truncation applies.
    case PsfKind::kMoffat:
      if (!PsfModel::Moffat(config.moffat).IsValid(&why)) fail(config, why);
      break;
    case PsfKind::kAiry:
      if (!PsfModel::Airy(config.airy).IsValid(&why)) fail(config, why);
      break;
    case PsfKind::kImage:
      if (config.psf_image.empty()) fail(config, "psf_input = image needs psf_image, the path of a FITS PSF image");
      break;
  }
  // A PSF given two ways is refused, not resolved silently in favour of one.
  if (config.psf_kind != PsfKind::kImage && !config.psf_image.empty())
    fail(config, "psf_image = " + quoted_value(config.psf_image, kQuotedPathMaxBytes) + " with psf_input = " + psf_input_value(config) +
                     ": the image would not be used; set psf_input = image to fit with it, or leave psf_image out");
  if (config.metacal.enabled) {
    if (!config.metacal.IsValid(&why)) fail(config, why);
    if (config.psf_kind == PsfKind::kAiry)
      fail(config, "metacal = true needs psf_input = moffat, moffat_catalog or image (the Airy disc's transform "
                   "vanishes beyond its cut-off: nothing to deconvolve there); psf_input = airy");
    if (!config.save_images.empty())
      fail(config, "save_images with metacal = true: not available (the row's fit is of the noshear image, with the "
                   "reconvolution PSF, not of the data the images would show)");
  }
  if (!(config.meds.min_unmasked_fraction >= 0 && config.meds.min_unmasked_fraction <= 1))
    fail(config, "meds_min_unmasked_fraction = " + format_double(config.meds.min_unmasked_fraction) + ": must be in [0, 1]");
  if (config.psf_upsampling < 1)
    fail(config, "psf_upsampling = " + std::to_string(config.psf_upsampling) + ": must be >= 1");
  if (config.batch_size < 1 || config.batch_size > 100000)
    fail(config, "batch_size = " + std::to_string(config.batch_size) + ": must be in [1, 100000]");
  const std::pair<const char*, const std::string*> columns[] = {
      {"catalog_id_column", &config.catalog_id_column},
      {"catalog_x_column", &config.catalog_x_column},
      {"catalog_y_column", &config.catalog_y_column},
      {"catalog_psf_beta_column", &config.catalog_psf_beta_column},
      {"catalog_psf_fwhm_column", &config.catalog_psf_fwhm_column},
      {"catalog_psf_e1_column", &config.catalog_psf_e1_column},
      {"catalog_psf_e2_column", &config.catalog_psf_e2_column},
  };
  for (const auto& [key, column] : columns)
    if (trim(*column).empty()) fail(config, std::string(key) + " = " + quoted_value(*column) + ": must name a catalogue column");
  std::vector<std::int64_t> ids;
  why = parse_id_list(config.save_images, &ids);
  if (!why.empty()) fail(config, "save_images = " + quoted_value(config.save_images) + ": " + why);
}

std::vector<std::pair<std::string, std::string>> effective_options(const RunConfig& config) {
  std::vector<std::pair<std::string, std::string>> out;
  out.reserve(registry().size());
  for (const Entry& e : registry()) out.emplace_back(e.name, e.get(config));
  return out;
}

std::string ini_template() {
  std::string out =
      "# stampede fit: run configuration (im3shape-style ini).\n"
      "# `key = value` per line; '#' starts a comment; [section] lines are ignored.\n"
      "# Every option is listed with its default, commented out: uncomment a line to change it.\n"
      "# Any key can also be given on the command line: --set key=value (after the file).\n";
  const RunConfig defaults;
  std::string section;
  for (const Entry& e : registry()) {
    if (e.section != section) {
      section = e.section;
      out += "\n# --- " + section + " ---\n";
    }
    const std::string value = e.get(defaults);
    out += "# " + e.help + "\n#" + e.name + (value.empty() ? " =" : " = " + value) + "\n";
  }
  return out;
}

std::vector<std::int64_t> save_image_ids(const RunConfig& config) {
  std::vector<std::int64_t> ids;
  const std::string why = parse_id_list(config.save_images, &ids);
  if (!why.empty()) throw ConfigError("save_images = " + quoted_value(config.save_images) + ": " + why);
  return ids;
}

}  // namespace stampede::io
