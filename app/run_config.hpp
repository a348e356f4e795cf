// The run's recipe: every engine and run option of `stampede fit` as typed values, read from an
// im3shape-style ini file plus `--set key=value` overrides, validated once before any fitting, and
// written back out (the output header, `--show-config`, `--help-config`).
//
// The text side is io/'s option registry (io/option_registry.hpp: parsing, printing, the ini
// syntax); this file says which keys there are and which field each sets (run_config.cpp), so
// defaults, parsing, documentation and the header cannot disagree. Values print in a canonical
// form that parses back to the identical value: doubles as the shortest text that round-trips
// exactly, NaN starts and bounds as `auto`, infinite bounds as `inf` / `-inf`, booleans as
// `true` / `false`. Keys are case-sensitive (im3shape's `levmar_LM_INIT_MU`); enum and boolean
// values are not.
#pragma once

#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "engine/common/error.hpp"
#include "engine/fit/fitter.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/model/psf_model.hpp"
#include "io/config_error.hpp"
#include "io/header_value.hpp"
#include "io/meds_options.hpp"
#include "io/option_registry.hpp"
#include "kernels/psf_profile.hpp"

namespace stampede::app {

using io::ConfigError;

struct RunConfig {
  FitterOptions fitter;  // render, model, lm, params, noise_sigma (defaults as in those structs)
  MetacalOptions metacal;  // metacal, metacal_step, metacal_psf_dilation, metacal_fixnoise, metacal_seed
  io::MedsOptions meds;    // meds_*: survey input (`stampede fit --meds`)
  // psf_input = moffat | airy | image names the kind of the run's one PSF (from the psf_* keys, the
  // airy_* keys or psf_image); psf_input = moffat_catalog is not a kind but a source: a Moffat per
  // object from the catalog_psf_* columns (psf_kind is then kMoffat; see psf_input_value).
  PsfKind psf_kind = PsfKind::kMoffat;
  bool psf_from_catalogue = false;
  kernels::MoffatProfile moffat;      // psf_beta psf_fwhm psf_e1 psf_e2 psf_truncation
  kernels::AiryProfile airy;          // airy_lambda_over_d airy_obscuration
  std::string psf_image;              // path of a FITS PSF image (psf_input = image)
  int psf_upsampling = 1;             // samples of psf_image per data pixel, per side
  bool psf_pixel_integrated = true;   // psf_image samples are pixel integrals (not point samples)
  int batch_size = 32;                // stamps per batch (one task of the pipeline)
  std::string fft_wisdom;             // FFTW wisdom cache file; "" = none
  std::string catalog_id_column = "id";
  std::string catalog_x_column = "x";
  std::string catalog_y_column = "y";
  std::string catalog_psf_beta_column = "psf_beta";
  std::string catalog_psf_fwhm_column = "psf_fwhm";
  std::string catalog_psf_e1_column = "psf_e1";
  std::string catalog_psf_e2_column = "psf_e2";
  std::string save_images;  // comma-separated object ids whose model/residual images are saved; "" = none

  // Keys given explicitly, each with where it was set: "FILE:LINE" (load_ini), "--set" (apply_set)
  // or "" (set_option). The command replaces only an unset stamp_size by the input's STAMPSZ
  // (`explicitly_set.contains("stamp_size")`), and validate() points at the line of a bad value.
  std::map<std::string, std::string> explicitly_set;
};

// The text of psf_input: "moffat_catalog" for a catalogue source, else psf_kind_name(psf_kind).
std::string psf_input_value(const RunConfig& config);

// Every key, in documentation order (the order of the template and of effective_options).
const std::vector<io::OptionInfo>& run_config_options();

// Sets one key from text and records it in explicitly_set. Throws ConfigError
// "option 'KEY' = 'VALUE': <why>" for a value that does not parse (not a number, trailing junk, out
// of the type's range, a non-finite double where only finite ones make sense) and
// "unknown option 'KEY'" (with a suggestion when a key is close) for an unknown key. On error the
// config is unchanged. Range constraints between values are validate()'s job.
void set_option(RunConfig& config, const std::string& key, const std::string& value);

// The canonical text of a key's value; set_option(get_option(c, k)) reproduces it exactly.
// Throws ConfigError for an unknown key.
std::string get_option(const RunConfig& config, const std::string& key);

// Reads an ini file (io/option_registry.hpp) into config. Errors name the file and line:
// "run.ini:12: unknown option 'foo'", "run.ini:3: expected 'key = value'",
// "run.ini:7: option 'padding' = 'x': ...", "cannot read config file 'x.ini'".
// All or nothing: on error the config is unchanged.
void load_ini(RunConfig& config, const std::string& path);

// Applies one `key=value` from the command line (split at the first '=', both sides trimmed).
// Errors are set_option's prefixed by "--set key=value: ".
void apply_set(RunConfig& config, const std::string& assignment);

// Whole-config validation once all keys are set: FitterOptions::IsValid and PsfModel::IsValid
// (the engine's messages, which name the key and value), then the run options: automatic bounds
// only for x0 and y0, psf_upsampling >= 1, psf_image given when psf_input = image, batch_size in
// [1, 100000], non-empty catalogue column names, parseable save_images. Throws ConfigError naming
// the key, prefixed by "FILE:LINE: " when that key came from an ini file.
void validate(const RunConfig& config);

// Every key with its value in config, in registry order (output header, `--show-config`).
std::vector<std::pair<std::string, std::string>> effective_options(const RunConfig& config);

// An ini file documenting every option: a comment with its help, then `#key = default`, commented
// out so that loading the template changes nothing (`stampede fit --help-config`).
std::string ini_template();

// The ids listed in save_images, in the given order. Throws ConfigError if it does not parse.
std::vector<std::int64_t> save_image_ids(const RunConfig& config);

}  // namespace stampede::app
