// `stampede sim meds`: a simulated multi-epoch MEDS tile (app/meds_simulation).
#include "tools/sim_meds_command.hpp"

#include <tbb/global_control.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <set>
#include <string>
#include <vector>

#include "app/meds_simulation.hpp"
#include "io/result_columns.hpp"
#include "tools/arguments.hpp"
#include "tools/field_flags.hpp"

namespace {

using namespace stampede;

void print_help() {
  const MedsSimOptions d;
  std::printf(
      "usage: stampede sim meds --out DIR [options]\n"
      "\n"
      "Writes a multi-epoch MEDS tile with a known constant shear: DIR/meds.fits (image, weight, seg\n"
      "and bmask cutouts; cutout 0 an empty coadd slot, cutouts 1..epochs the single epochs),\n"
      "DIR/psfex/image_K.psf (each source image's PSF, a constant PSFEx model), DIR/truth.fits\n"
      "(SHEAR1 SHEAR2; a TRUTH row per object: id index number pair e1_int e2_int e1_obs e2_obs hlr\n"
      "flux bulge_frac u0 v0 neighbour; stampede metrics reads it). Each cutout has a random affine WCS (any rotation, pixel scale\n"
      "within +-3%%, WCS shear within +-0.02), the PSF and zero point of its source image (an\n"
      "object's epochs use distinct images). Objects 2m, 2m+1 are a 90-degree ring pair seen\n"
      "through the same epochs. Galaxies: co-elliptical bulge + disc drawn by the exact renderer\n"
      "with the PSFEx samples. e is in the (u, v) frame of the Jacobians. Fit it with\n"
      "`stampede fit --meds DIR/meds.fits -o OUT.fits`. Deterministic for a seed, any thread count.\n"
      "\n"
      "  --out DIR              output directory, created if missing (required)\n"
      "  --objects N            objects, even (%d)\n"
      "  --epochs N             single-epoch cutouts per object (%d)\n"
      "  --images N             source images, each with its own PSF, >= epochs (%d)\n"
      "  --box-size N           cutout side, pixels (%d)\n"
      "  --shear G1,G2          the constant shear (%g,%g)\n"
      "  --snr X                each object's S/N over all its epochs (%g)\n"
      "  --noise-sigma S        noise per pixel, every epoch (%g)\n"
      "  --noise-free           no noise (fluxes still set by --snr)\n"
      "  --pixel-scale S        arcsec per pixel (%g)\n"
      "  --scale-jitter F       each cutout's pixel scale within +-F (%g)\n"
      "  --wcs-shear S          each cutout's WCS shear components within +-S (%g)\n"
      "  --no-rotation          no WCS rotations (with --pixel-scale 1 and no jitter or WCS shear:\n"
      "                         identity Jacobians, the cutouts' pixels are the sky)\n"
      "  --magzp-jitter M       each image's zero point 30 +- M (%g)\n"
      "  --psf-fwhm MIN,MAX     Moffat FWHM range, arcsec (%g,%g; beta %g)\n"
      "  --psf-e-max E          each PSF's e1, e2 within +-E (%g)\n"
      "  --hlr MIN,MAX          disc half-light radius range, arcsec (%g,%g)\n"
      "  --psf-cutouts          also write each cutout's PSF image into the tile (HDU 'psf'), which\n"
      "                         `fit --meds` then uses (meds_psf = auto)\n"
      "  --bad-columns F        probability per cutout of a hot column, flagged in bmask (%g)\n"
      "  --neighbours F         probability per ring pair of a neighbour 2.2-3 arcsec away, with a\n"
      "                         seg map (%g)\n"
      "  --bands B1,B2,...      one tile per band of the same galaxies (up to 8; names as column\n"
      "                         suffixes): DIR/B/meds.fits, DIR/B/truth.fits (the band's flux and\n"
      "                         bulge_frac) and DIR/B/psfex; each band has its own images (PSF FWHM\n"
      "                         scaled from 1 to 0.9 over the bands, zero points 0.25 mag apart),\n"
      "                         epochs, WCSs and noise, the bulge fraction scaled from 0.5x to 1.5x,\n"
      "                         and --snr in each band. Fit them with `stampede fit --meds\n"
      "                         DIR/B1/meds.fits --meds DIR/B2/meds.fits ... --bands B1,B2,...`\n"
      "  --seed N               random seed (%llu)\n"
      "  --threads N            worker threads (default: all cores)\n"
      "  --overwrite            replace an existing tile and truth\n",
      d.objects, d.epochs, d.images, d.box_size, d.g1, d.g2, d.snr, d.noise_sigma, d.pixel_scale, d.scale_jitter,
      d.wcs_shear, d.magzp_jitter, d.psf_fwhm_min, d.psf_fwhm_max,
      d.psf_beta, d.psf_e_max, d.hlr_min, d.hlr_max, d.bad_column_fraction, d.neighbour_fraction,
      static_cast<unsigned long long>(d.seed));
}

std::pair<double, double> pair_of(const std::string& option, const std::string& text) {
  const std::array<double, 2> v = tools::number_pair(option, text, "two numbers A,B");
  return {v[0], v[1]};
}

}  // namespace

int run_sim_meds_command(int argc, char** argv) {
  MedsSimOptions o;
  std::string out;
  int threads = 0;
  bool overwrite = false;
  std::vector<std::string> bands;
  std::set<std::string> seen;
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    tools::refuse_repeated_option(s, {"--help", "--noise-free", "--no-rotation", "--psf-cutouts", "--overwrite"}, &seen,
                                  "sim meds");
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    auto number = [&] { return tools::number_value(argc, argv, &i); };
    if (s == "--help" || s == "-h") {
      print_help();
      return 0;
    } else if (s == "--out") {
      out = value();
    } else if (s == "--objects") {
      o.objects = static_cast<int>(tools::integer_in(argc, argv, &i, 2, 100000000));
    } else if (s == "--epochs") {
      o.epochs = static_cast<int>(tools::integer_in(argc, argv, &i, 1, 64));
    } else if (s == "--images") {
      o.images = static_cast<int>(tools::integer_in(argc, argv, &i, 1, 100000));
    } else if (s == "--box-size") {
      o.box_size = static_cast<int>(tools::integer_in(argc, argv, &i, 16, 512));
    } else if (s == "--shear") {
      std::tie(o.g1, o.g2) = pair_of(s, value());
    } else if (s == "--snr") {
      o.snr = number();
    } else if (s == "--noise-sigma") {
      o.noise_sigma = number();
    } else if (s == "--noise-free") {
      o.noise_free = true;
    } else if (s == "--pixel-scale") {
      o.pixel_scale = number();
    } else if (s == "--scale-jitter") {
      o.scale_jitter = number();
    } else if (s == "--wcs-shear") {
      o.wcs_shear = number();
    } else if (s == "--no-rotation") {
      o.rotate = false;
    } else if (s == "--magzp-jitter") {
      o.magzp_jitter = number();
    } else if (s == "--psf-fwhm") {
      std::tie(o.psf_fwhm_min, o.psf_fwhm_max) = pair_of(s, value());
    } else if (s == "--psf-e-max") {
      o.psf_e_max = number();
    } else if (s == "--hlr") {
      std::tie(o.hlr_min, o.hlr_max) = pair_of(s, value());
    } else if (s == "--psf-cutouts") {
      o.psf_cutouts = true;
    } else if (s == "--bad-columns") {
      o.bad_column_fraction = number();
    } else if (s == "--neighbours") {
      o.neighbour_fraction = number();
    } else if (s == "--bands") {
      const std::string v = value();
      bands.clear();
      for (std::size_t begin = 0;;) {
        const std::size_t comma = v.find(',', begin);
        bands.push_back(v.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
        if (comma == std::string::npos) break;
        begin = comma + 1;
      }
      std::string why;
      if (!io::are_band_names(bands, &why)) throw std::invalid_argument("--bands " + tools::quoted_value(v) + ": " + why);
      if (bands.size() > 8) throw std::invalid_argument("--bands " + tools::quoted_value(v) + ": at most 8 bands");
    } else if (s == "--seed") {
      o.seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, (1LL << 62)));
    } else if (s == "--threads") {
      threads = static_cast<int>(tools::integer_in(argc, argv, &i, 1, 4096));
    } else if (s == "--overwrite") {
      overwrite = true;
    } else {
      throw std::invalid_argument("unknown option " + tools::quoted_value(s) + " (see stampede sim meds --help)");
    }
  }
  if (out.empty()) throw std::invalid_argument("--out DIR is required (see stampede sim meds --help)");
  // The simulator's rules name its fields: the command line's words are its flags.
  static const tools::FieldFlags kFlags = {
      {"objects", "--objects"},          {"epochs", "--epochs"},
      {"images", "--images"},            {"box_size", "--box-size"},
      {"pixel_scale", "--pixel-scale"},  {"scale_jitter", "--scale-jitter"},
      {"wcs_shear", "--wcs-shear"},      {"psf_fwhm_min, psf_fwhm_max", "--psf-fwhm"},
      {"psf_e_max", "--psf-e-max"},      {"g1, g2", "--shear"},
      {"snr", "--snr"},                  {"noise_sigma", "--noise-sigma"},
      {"hlr_min, hlr_max", "--hlr"},     {"magzp_jitter", "--magzp-jitter"},
      {"bad_column_fraction", "--bad-columns"}, {"neighbour_fraction", "--neighbours"}};
  std::string why;
  if (!o.IsValid(&why)) throw std::invalid_argument(tools::with_flags(why, kFlags));
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  if (bands.empty()) {
    app::write_meds_simulation(o, out, overwrite, [](long long done, long long total) {
      std::fprintf(stderr, "\rstampede sim meds: %lld/%lld objects", done, total);
    });
    std::fprintf(stderr, "\nstampede sim meds: wrote %s/meds.fits, %s/truth.fits and %d PSFEx models\n", out.c_str(),
                 out.c_str(), o.images);
    return 0;
  }
  o.bands = static_cast<int>(bands.size());
  for (std::size_t b = 0; b < bands.size(); ++b) {
    o.band = static_cast<int>(b);
    const std::string dir = out + "/" + bands[b];
    app::write_meds_simulation(o, dir, overwrite, [&](long long done, long long total) {
      std::fprintf(stderr, "\rstampede sim meds: band %s: %lld/%lld objects", bands[b].c_str(), done, total);
    });
    std::fprintf(stderr, "\nstampede sim meds: wrote %s/meds.fits, %s/truth.fits and %d PSFEx models\n", dir.c_str(),
                 dir.c_str(), o.images);
  }
  return 0;
}
