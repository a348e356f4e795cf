// The run recipe's keys (each one a field of RunConfig) and its validation; see run_config.hpp.
#include "app/run_config.hpp"

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


namespace stampede::app {
namespace {

using io::DoubleKind;
using io::format_double;
using io::format_id_list;
using io::format_bool;
using io::parse_bool;
using io::parse_double;
using io::parse_integer;
using io::HeaderValueType;
using io::parse_id_list;

using io::lower;
using io::MedsModel;
using io::MedsPsfSource;
using io::trim;

// psf_input's value for a catalogue source of Moffat PSFs (psf_kind_name names the kinds).
constexpr const char* kMoffatCatalog = "moffat_catalog";

// --- The registry ---------------------------------------------------------------------------

using Entry = io::OptionEntry<RunConfig>;

template <class Access>
Entry int_entry(const char* section, const char* name, const char* help, Access access) {
  return io::int_option<RunConfig>(section, name, help, access);
}
template <class Access>
Entry double_entry(const char* section, std::string name, std::string help, DoubleKind kind, Access access) {
  return io::double_option<RunConfig>(section, std::move(name), std::move(help), kind, access);
}
template <class Access>
Entry bool_entry(const char* section, std::string name, std::string help, Access access) {
  return io::bool_option<RunConfig>(section, std::move(name), std::move(help), access);
}
template <class Access>
Entry string_entry(const char* section, const char* name, const char* help, Access access) {
  return io::string_option<RunConfig>(section, name, help, access);
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
  r.push_back(double_entry(mcal, "metacal_step",
                           "metacal: the applied shear delta, in [0.001, 0.1] (below 0.001 errors in e swamp R: "
                           "docs/metacal.md)",
                           DoubleKind::kFinite, [](auto& c) -> auto& { return c.metacal.step; }));
  r.push_back({"metacal_reconvolution_psf",
               "metacal: the reconvolution PSF: gauss, a round Gaussian, the PSF's adaptive Gaussian on its major axis "
               "dilated by 1 + 2 metacal_step (the reference metadetect package's fitgauss); moffat, a round Moffat "
               "widened until its filters are <= 1.01; auto (default): the Gaussian where its filters are <= 1.01 too "
               "(Gaussian-like PSFs), else moffat; gauss accepts filters up to 1.5",
               mcal, [](const RunConfig& c) { return std::string(reconvolution_rule_name(c.metacal.reconvolution)); },
               [](RunConfig& c, const std::string& v) {
                 if (!parse_reconvolution_rule(v, &c.metacal.reconvolution))
                   return std::string("expected auto, gauss or moffat");
                 return std::string();
               }});
  r.push_back(double_entry(mcal, "metacal_psf_dilation",
                           "metacal: reconvolution PSF FWHM over the PSF's (a Gaussian's over the PSF's adaptive "
                           "Gaussian's); 0 = the rule's own: a Gaussian's 1 + 2 metacal_step, a Moffat's (1 + 2 "
                           "metacal_step) sqrt((1 + |e|) / (1 - |e|)), the smallest wider than the sheared PSF in every "
                           "direction",
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
const io::OptionRegistry<RunConfig>& registry() {
  static const io::OptionRegistry<RunConfig> options(make_registry());
  return options;
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

const std::vector<io::OptionInfo>& run_config_options() {
  static const std::vector<io::OptionInfo> options = registry().options();
  return options;
}

void set_option(RunConfig& config, const std::string& key, const std::string& value) {
  registry().set(config, key, value);
}

std::string get_option(const RunConfig& config, const std::string& key) { return registry().get(config, key); }

void load_ini(RunConfig& config, const std::string& path) { registry().load_ini(config, path); }

void apply_set(RunConfig& config, const std::string& assignment) { registry().apply_set(config, assignment); }

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
    case PsfKind::kGaussian:  // not a psf_input (parse_psf_kind refuses it)
      fail(config, "psf_input = gaussian: not an input PSF (moffat, airy or image)");
      break;
  }
  // A PSF given two ways is refused, not resolved silently in favour of one.
  if (config.psf_kind != PsfKind::kImage && !config.psf_image.empty())
    fail(config, "psf_image = " + quoted_value(config.psf_image, kQuotedPathMaxBytes) + " with psf_input = " + psf_input_value(config) +
                     ": the image would not be used; set psf_input = image to fit with it, or leave psf_image out");
  if (config.metacal.enabled) {
    if (!config.metacal.IsValid(&why)) fail(config, why);
    // The weight is the moments' (wmom); a model fit has none, and would ignore it silently.
    if (config.metacal.weight_fwhm != 0 && config.metacal.model != MetacalModel::kWeightedMoments)
      fail(config, "metacal_weight_fwhm = " + format_double(config.metacal.weight_fwhm) + " with metacal_model = " +
                       get_option(config, "metacal_model") +
                       ": it is the wmom moments' weight, and a model fit has none (leave metacal_weight_fwhm out, "
                       "or set metacal_model = wmom)");
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
  return registry().effective(config);
}

std::string ini_template() {
  return registry().ini_template(
      "# stampede fit: run configuration (im3shape-style ini).\n"
      "# `key = value` per line; '#' starts a comment; [section] lines are ignored.\n"
      "# Every option is listed with its default, commented out: uncomment a line to change it.\n"
      "# Any key can also be given on the command line: --set key=value (after the file).\n");
}

std::vector<std::int64_t> save_image_ids(const RunConfig& config) {
  std::vector<std::int64_t> ids;
  const std::string why = parse_id_list(config.save_images, &ids);
  if (!why.empty()) throw ConfigError("save_images = " + quoted_value(config.save_images) + ": " + why);
  return ids;
}

}  // namespace stampede::app
