// `stampede sim cells`: metadetection test cells (app/cell_simulation, engine/sim/cell_sim).
#include "tools/sim_cells_command.hpp"

#include <tbb/global_control.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <set>
#include <string>
#include <vector>

#include "app/cell_simulation.hpp"
#include "tools/arguments.hpp"
#include "tools/field_flags.hpp"

namespace {

using namespace stampede;

void print_help() {
  const CellSimOptions d;
  std::printf(
      "usage: stampede sim cells --out DIR [options]\n"
      "\n"
      "Writes metadetection test cells (the metadetect shear test's simulation by default): square\n"
      "cells of galaxies under one constant shear, on a grid or at random positions (blends), with a\n"
      "Gaussian or Moffat PSF and white noise set by a per-object S/N. Galaxies are exact\n"
      "PSF-convolved pixel integrals, each in a stamp holding all but 1e-5 of its light.\n"
      "Deterministic for a seed, whatever the thread count.\n"
      "\n"
      "outputs (one band: BDIR = DIR; several: BDIR = DIR/<band>):\n"
      "  BDIR/cell_KKKK.fits    HDU 0 the image (float32; header SCALE G1 G2 PSFTYPE PSFFWHM [PSFBETA]\n"
      "                         NOISESIG SNR SEED CELL NOBJ ...), WEIGHT (1/sigma^2), BMASK (zeros, int32),\n"
      "                         NOISE (an independent noise field of the same sigma), PSF (pixel-\n"
      "                         integrated, --psf-size square, centred on its middle pixel)\n"
      "  BDIR/cells_meds.fits   with --tile: the cells as a cell tile (MEDS, a row per cell: cutout 0\n"
      "                         the cell, with weight, seg, bmask, noise and psf cutouts)\n"
      "  DIR/truth.fits         SHEAR1 SHEAR2; TRUTH a row per object: cell id x y (0-based pixels)\n"
      "                         flux hlr bulge_frac e1_int e2_int e1_obs e2_obs snr g1 g2 [flux_<band>]\n"
      "  DIR/minus/...          with --pair: the same cells under the opposite shear (same galaxies and\n"
      "                         noise, positions sheared with the scene), laid out as DIR\n"
      "\n"
      "options:\n"
      "  --out DIR              output directory, created if missing (required)\n"
      "  --cells N              number of cells (1)\n"
      "  --size N               cell side, pixels (%d)\n"
      "  --pixel-scale S        arcsec per pixel (%g)\n"
      "  --buffer N             edge buffer, pixels: the grid stays inside it (%d)\n"
      "  --layout grid|random   grid: --grid^2 objects evenly inside the buffer, each shifted by\n"
      "                         U(-shift, shift) px; random: Poisson positions over the whole cell (%s)\n"
      "  --grid N               objects per side of the grid (%d)\n"
      "  --grid-shift PX        the grid's random shift per axis (%g)\n"
      "  --density D            random: mean objects per arcmin^2 (%g)\n"
      "  --model exp|bd         exponential, or co-elliptical de Vaucouleurs bulge + exponential disc\n"
      "                         of one radius, bulge fraction ~ U[0, --bulge-fraction-max] (%s)\n"
      "  --hlr R                half-light radius sqrt(ab), arcsec (%g)\n"
      "  --flux F               each galaxy's flux in the first band (%g)\n"
      "  --bulge-fraction-max F bd: the bulge fraction's upper limit (%g)\n"
      "  --shape-noise S        intrinsic e per component ~ N(0, S), |e| < --e-max; 0: round (%g)\n"
      "  --e-max E              (%g)\n"
      "  --shear G1,G2          the shear applied to every galaxy's intrinsic shape (%g,%g)\n"
      "  --pair                 also write the cells under the opposite shear in DIR/minus\n"
      "  --psf gauss|moffat     PSF profile (%s)\n"
      "  --psf-fwhm F           PSF FWHM, arcsec, first band (%g)\n"
      "  --psf-beta B           Moffat beta (%g)\n"
      "  --psf-size N           PSF image side, odd (%d)\n"
      "  --snr X                per-object S/N: noise sigma = sqrt(sum I^2) / X for a round reference\n"
      "                         galaxy drawn alone, summed over bands (one sigma for all bands) (%g)\n"
      "  --reference-positions  positions as the reference package's shear test draws them: the grid\n"
      "                         spans the inner region edge to edge; random: int(density x the inner\n"
      "                         region's area) objects uniform over it; each shifted by --grid-shift\n"
      "  --reference            the reference package's shear test cell: --reference-positions,\n"
      "                         --snr 1e6, --shape-noise 0, --psf-size 53 (options given override)\n"
      "  --keep-clear PX        random: no object within PX px of the buffer's inner edge (objects\n"
      "                         there cross it under the shear: noise in a one-cell test) (0)\n"
      "  --rotate               the scene turned by 90 degrees about each cell's centre (intrinsic\n"
      "                         shapes negated, positions rotated, the same noise): with the unrotated\n"
      "                         cells it cancels shape noise in a shear test (metrics --rotated)\n"
      "  --noise-free           noise sigma 1e-6 of --snr's: essentially noiseless, with NOISE and\n"
      "                         WEIGHT consistent with it\n"
      "  --bands B1,B2,...      one image per band of the same galaxies (up to 8), in DIR/<band>: band\n"
      "                         b of B has flux x (1 + 0.5 b/(B-1)), PSF FWHM x (1 - 0.1 b/(B-1)), bd\n"
      "                         bulge fraction x (0.5 + b/(B-1)) (capped at 1)\n"
      "  --stars N              bright stars per cell: unlensed point sources at whole pixels, the\n"
      "                         same under either shear, flux log-uniform in [10, --star-flux] x\n"
      "                         --flux; each image gets a table STARS (x, y, mask radius) for\n"
      "                         metadetect --star-mask-hdu STARS (0)\n"
      "  --star-flux F          the brightest star's flux over a galaxy's (1000)\n"
      "  --bad-columns N        bad columns per cell: vertical runs of hot pixels (1e3 sigma) at least\n"
      "                         a quarter of the cell long, the same under either shear, flagged in\n"
      "                         each image's BMASK (bit 1) (0)\n"
      "  --tile                 also write the cells as a cell tile (cells_meds.fits)\n"
      "  --seed N               random seed (%llu)\n"
      "  --threads N            worker threads (default: all cores)\n"
      "  --overwrite            replace existing outputs\n",
      d.size, d.pixel_scale, d.buffer, cell_layout_name(d.layout), d.grid, d.grid_shift, d.density,
      cell_galaxy_model_name(d.model), d.hlr, d.flux, d.bulge_fraction_max, d.shape_noise, d.e_max, d.g1, d.g2,
      cell_psf_kind_name(d.psf), d.psf_fwhm, d.psf_beta, d.psf_size, d.snr, static_cast<unsigned long long>(d.seed));
}

std::vector<std::string> split(const std::string& v) {
  std::vector<std::string> out;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = v.find(',', begin);
    out.push_back(v.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
    if (comma == std::string::npos) return out;
    begin = comma + 1;
  }
}

}  // namespace

int run_sim_cells_command(int argc, char** argv) {
  CellSimOptions o;
  app::CellOutputOptions out;
  std::string dir;
  int threads = 0;
  std::set<std::string> seen;
  // The reference test's cell first, so that options given with it override its settings.
  for (int i = 2; i < argc; ++i)
    if (std::string(argv[i]) == "--reference") {
      o.reference_positions = true, o.snr = 1e6, o.shape_noise = 0, o.psf_size = 53;
      break;
    }
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    tools::refuse_repeated_option(s, {"--help", "--pair", "--rotate", "--noise-free", "--tile", "--overwrite",
                                      "--reference", "--reference-positions"},
                                  &seen, "sim cells");
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    auto number = [&] { return tools::number_value(argc, argv, &i); };
    auto integer = [&](long long lo, long long hi) { return static_cast<int>(tools::integer_in(argc, argv, &i, lo, hi)); };
    if (s == "--help" || s == "-h") {
      print_help();
      return 0;
    } else if (s == "--out") {
      dir = value();
    } else if (s == "--cells") {
      out.cells = integer(1, 10000000);
    } else if (s == "--size") {
      o.size = integer(16, 4096);
    } else if (s == "--pixel-scale") {
      o.pixel_scale = number();
    } else if (s == "--buffer") {
      o.buffer = integer(0, 2048);
    } else if (s == "--layout") {
      const std::string v = value();
      if (!parse_cell_layout(v, &o.layout))
        throw std::invalid_argument("option --layout: " + tools::quoted_value(v) + " is not grid or random");
    } else if (s == "--grid") {
      o.grid = integer(1, 1000);
    } else if (s == "--grid-shift") {
      o.grid_shift = number();
    } else if (s == "--density") {
      o.density = number();
    } else if (s == "--model") {
      const std::string v = value();
      if (!parse_cell_galaxy_model(v, &o.model))
        throw std::invalid_argument("option --model: " + tools::quoted_value(v) + " is not exp or bd");
    } else if (s == "--hlr") {
      o.hlr = number();
    } else if (s == "--flux") {
      o.flux = number();
    } else if (s == "--bulge-fraction-max") {
      o.bulge_fraction_max = number();
    } else if (s == "--shape-noise") {
      o.shape_noise = number();
    } else if (s == "--e-max") {
      o.e_max = number();
    } else if (s == "--shear") {
      const std::array<double, 2> g = tools::number_pair(s, value(), "two numbers G1,G2");
      o.g1 = g[0], o.g2 = g[1];
    } else if (s == "--pair") {
      out.pair = true;
    } else if (s == "--psf") {
      const std::string v = value();
      if (!parse_cell_psf_kind(v, &o.psf))
        throw std::invalid_argument("option --psf: " + tools::quoted_value(v) + " is not gauss or moffat");
    } else if (s == "--psf-fwhm") {
      o.psf_fwhm = number();
    } else if (s == "--psf-beta") {
      o.psf_beta = number();
    } else if (s == "--psf-size") {
      o.psf_size = integer(5, 255);
    } else if (s == "--snr") {
      o.snr = number();
    } else if (s == "--keep-clear") {
      o.keep_clear = number();
    } else if (s == "--reference") {
      // applied above
    } else if (s == "--reference-positions") {
      o.reference_positions = true;
    } else if (s == "--rotate") {
      o.rotate = true;
    } else if (s == "--noise-free") {
      o.noise_free = true;
    } else if (s == "--bands") {
      const std::string v = value();
      out.band_names = split(v);
      if (out.band_names.size() > 8) throw std::invalid_argument("option --bands " + tools::quoted_value(v) + ": at most 8 bands");
      o.bands = static_cast<int>(out.band_names.size());
    } else if (s == "--stars") {
      o.stars = integer(0, 1000);
    } else if (s == "--star-flux") {
      o.star_flux = number();
    } else if (s == "--bad-columns") {
      o.bad_columns = integer(0, 100);
    } else if (s == "--tile") {
      out.tile = true;
    } else if (s == "--seed") {
      o.seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, (1LL << 62)));
    } else if (s == "--threads") {
      threads = integer(1, 4096);
    } else if (s == "--overwrite") {
      out.overwrite = true;
    } else {
      throw std::invalid_argument("unknown option " + tools::quoted_value(s) + " (see stampede sim cells --help)");
    }
  }
  if (dir.empty()) throw std::invalid_argument("--out DIR is required (see stampede sim cells --help)");
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  // The simulator's rules name its fields: the command line's words are its flags.
  static const tools::FieldFlags kFlags = {
      {"cells", "--cells"},           {"band_names", "--bands"},         {"bands", "--bands"},
      {"size", "--size"},             {"pixel_scale", "--pixel-scale"},  {"buffer", "--buffer"},
      {"grid", "--grid"},             {"grid_shift", "--grid-shift"},    {"density", "--density"},
      {"hlr", "--hlr"},               {"flux", "--flux"},                {"bulge_fraction_max", "--bulge-fraction-max"},
      {"shape_noise", "--shape-noise"}, {"keep_clear", "--keep-clear"},  {"e_max", "--e-max"},
      {"psf_fwhm", "--psf-fwhm"},     {"psf_beta", "--psf-beta"},        {"psf_size", "--psf-size"},
      {"g1, g2", "--shear"},          {"snr", "--snr"},                  {"stars", "--stars"},
      {"star_flux", "--star-flux"},   {"bad_columns", "--bad-columns"}};
  try {
    app::write_cell_simulation(o, out, dir, [](int done, int total) {
      std::fprintf(stderr, "\rstampede sim cells: %d/%d cells", done, total);
    });
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(tools::with_flags(e.what(), kFlags));
  }
  std::fprintf(stderr, "\nstampede sim cells: wrote %d cell%s%s%s to %s\n", out.cells, out.cells == 1 ? "" : "s",
               out.pair ? " and their shear pairs" : "", out.tile ? " (and cell tiles)" : "", dir.c_str());
  return 0;
}
