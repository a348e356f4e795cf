// `stampede sim`; see sim_command.hpp.
#include "tools/sim_command.hpp"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/sim/great08_sim.hpp"
#include "io/great08_writer.hpp"
#include "io/output_check.hpp"
#include "io/option_text.hpp"
#include "tools/arguments.hpp"
#include "tools/field_flags.hpp"
#include "tools/sim_cells_command.hpp"
#include "tools/sim_meds_command.hpp"

namespace {

// The simulator's messages name its fields; the command line's words are these flags.
const stampede::tools::FieldFlags kGreat08Flags = {
    {"sets", "--sets"},
    {"grid", "--grid"},
    {"stamp_size", "--stamp"},
    {"snr", "--snr"},
    {"noise_sigma", "--noise-sigma"},
    {"size_ratio", "--size"},
    {"psf", "--psf"},
    {"psf_fwhm", "--psf-fwhm"},
    {"e_sigma", "--e-sigma"},
    {"e_max", "--e-max"},
    {"shear_max", "--shear-max"},
    {"shear", "--shear"},
    {"centre_offset", "--centre-offset"},
    {"bulge_fraction", "--bulge-fraction"},
    {"bd_radius_ratio", "--bd-radius-ratio"},
    {"bd_misalignment", "--bd-misalignment"},
    {"bd_offset", "--bd-offset"}};

}  // namespace

namespace {

using namespace stampede;

void print_help() {
  const Great08SimOptions d;
  std::printf(
      "usage: stampede sim great08 --out DIR [options]\n"
      "       stampede sim meds --out DIR [options]   (multi-epoch MEDS tiles: sim meds --help)\n"
      "       stampede sim cells --out DIR [options]  (metadetection test cells: sim cells --help)\n"
      "\n"
      "Writes GREAT08-like constant-shear sets K = first .. first + sets - 1 in the layout of\n"
      "shared/data/galsim-great08-mini: DIR/set_K.fits (float32 grid of stamps, PSF and noise keys),\n"
      "DIR/truth_K.fits (SHEAR1 SHEAR2, a TRUTH row per object) and DIR/psf_K.fits (pixel-integrated\n"
      "PSF, and PSF_NOPIX_OS at 5x without the pixel). Objects 2m and 2m+1 are a 90-degree ring pair.\n"
      "Galaxies are exact pixel integrals drawn in Fourier space (GalSim's reference cases to ~1e-6\n"
      "of the peak). Deterministic for a seed, whatever the thread count.\n"
      "\n"
      "output:\n"
      "  --out DIR                 output directory, created if missing (required)\n"
      "  --sets N                  number of sets (%d)\n"
      "  --first-set K             index of the first set (0): split a run over jobs, same seed\n"
      "  --overwrite               replace existing files (default: refuse)\n"
      "  --threads N               worker threads (default: all cores)\n"
      "image:\n"
      "  --grid N                  stamps per side, N^2 objects per set (%d)\n"
      "  --stamp S                 stamp size in pixels (%d)\n"
      "  --snr X                   sqrt(sum I^2) / sigma of every noise-free stamp (%g)\n"
      "  --noise-sigma S           Gaussian noise per pixel; also the flux reference (%g)\n"
      "  --noise-free              no noise (fluxes still set by --snr and --noise-sigma)\n"
      "  --noise-pairs             objects 4q+2, 4q+3 repeat the ring pair 4q, 4q+1 with the noise\n"
      "                            negated (pair label q for all four): odd noise orders cancel in\n"
      "                            the group mean, so noise bias is measured with far less scatter\n"
      "  --shear-pairs             set 2j+1 repeats set 2j (galaxies and noise) under the opposite\n"
      "                            shear: metrics --shear-pairs then cancels the noise common to both\n"
      "PSF:\n"
      "  --psf moffat|airy         profile (moffat)\n"
      "  --psf-beta B --psf-fwhm F Moffat beta (%g) and FWHM in pixels (%g)\n"
      "  --psf-e1 E --psf-e2 E     PSF ellipticity, reduced shear (%g, %g)\n"
      "  --psf-trunc R             Moffat truncation radius in pixels (0 = none)\n"
      "  --airy-lambda-over-d L    Airy lambda/D in pixels (2.77: FWHM 2.85)\n"
      "galaxies:\n"
      "  --galaxy TYPE             bd (co-elliptical bulge + disc, equal radii), b+d (different radii,\n"
      "                            misaligned shapes, offset centres), bulge, disc (%s)\n"
      "  --size R                  Rgp/Rp: FWHM of round galaxy (x) PSF over PSF FWHM, no pixel (%g)\n"
      "  --bulge-fraction MIN,MAX  bulge flux fraction ~ U[MIN, MAX] for bd and b+d (0,1)\n"
      "  --bd-radius-ratio R       b+d: bulge / disc half-light radius (%g)\n"
      "  --bd-misalignment DEG     b+d: sigma of the bulge position angle about the disc's (%g)\n"
      "  --bd-offset PX            b+d: bulge centre offset, uniform within this radius (%g)\n"
      "  --e-sigma S --e-max E     intrinsic e per component ~ N(0, S), |e| < E (%g, %g)\n"
      "  --centre-offset A         centre ~ stamp centre + U[-A, A) per axis (%g)\n"
      "shear and seed:\n"
      "  --shear-max G             each set's g1, g2 ~ U(-G, G) (%g)\n"
      "  --shear G1,G2             every set's shear instead (the odd set of a shear pair: -G1,-G2)\n"
      "  --seed S                  master seed (%llu)\n",
      d.sets, d.grid, d.stamp_size, d.snr, d.noise_sigma, d.psf.moffat.beta, d.psf.moffat.fwhm, d.psf.moffat.e1,
      d.psf.moffat.e2, sim_galaxy_type_name(d.galaxy_type), d.size_ratio, d.bd_radius_ratio, d.bd_misalignment_deg,
      d.bd_offset, d.e_sigma, d.e_max, d.centre_offset, d.shear_max, static_cast<unsigned long long>(d.seed));
}

std::string join_arguments(int argc, char** argv) {
  std::string s = "stampede";
  for (int i = 0; i < argc; ++i) s += std::string(" ") + argv[i];
  return s;
}

}  // namespace

int run_sim_command(int argc, char** argv) {
  // argv[0] = "sim", argv[1] = the kind of simulation.
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    print_help();
    return argc < 2 ? 2 : 0;
  }
  if (!std::strcmp(argv[1], "meds")) return run_sim_meds_command(argc, argv);
  if (!std::strcmp(argv[1], "cells")) return run_sim_cells_command(argc, argv);
  if (std::strcmp(argv[1], "great08") != 0)
    throw std::invalid_argument("unknown simulation " + tools::quoted_value(argv[1]) + " (available: great08, meds, cells)");
  using tools::number_value;
  Great08SimOptions o;
  std::string out;
  int first_set = 0, threads = 0;
  bool overwrite = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto int_in = [&](long long lo, long long hi) { return static_cast<int>(tools::integer_in(argc, argv, &i, lo, hi)); };
    if (a == "--help" || a == "-h") {
      print_help();
      return 0;
    } else if (a == "--out") out = tools::option_value(argc, argv, &i);
    else if (a == "--sets") o.sets = int_in(1, 10000);
    else if (a == "--first-set") first_set = int_in(0, 1000000);
    else if (a == "--overwrite") overwrite = true;
    else if (a == "--threads") threads = int_in(1, 4096);
    else if (a == "--grid") o.grid = int_in(1, 1000);
    else if (a == "--stamp") o.stamp_size = int_in(8, 512);
    else if (a == "--snr") o.snr = number_value(argc, argv, &i);
    else if (a == "--noise-sigma") o.noise_sigma = number_value(argc, argv, &i);
    else if (a == "--noise-free") o.noise_free = true;
    else if (a == "--noise-pairs") o.noise_pairs = true;
    else if (a == "--shear-pairs") o.shear_pairs = true;
    else if (a == "--psf") {
      const std::string v = tools::option_value(argc, argv, &i);
      if (v == "moffat") o.psf.kind = PsfKind::kMoffat;
      else if (v == "airy") o.psf.kind = PsfKind::kAiry;
      else throw std::invalid_argument("option --psf: " + tools::quoted_value(v) + " is not moffat or airy");
    } else if (a == "--psf-beta") o.psf.moffat.beta = number_value(argc, argv, &i);
    else if (a == "--psf-fwhm") o.psf.moffat.fwhm = number_value(argc, argv, &i);
    else if (a == "--psf-e1") o.psf.moffat.e1 = number_value(argc, argv, &i);
    else if (a == "--psf-e2") o.psf.moffat.e2 = number_value(argc, argv, &i);
    else if (a == "--psf-trunc") o.psf.moffat.truncation = number_value(argc, argv, &i);
    else if (a == "--airy-lambda-over-d") o.psf.airy.lambda_over_d = number_value(argc, argv, &i);
    else if (a == "--galaxy") {
      const std::string v = tools::option_value(argc, argv, &i);
      if (!parse_sim_galaxy_type(v, &o.galaxy_type))
        throw std::invalid_argument("option --galaxy: " + tools::quoted_value(v) + " is not bd, b+d, bulge or disc");
    } else if (a == "--size") o.size_ratio = number_value(argc, argv, &i);
    else if (a == "--bulge-fraction") {
      const auto range = tools::number_pair(a, tools::option_value(argc, argv, &i), "MIN,MAX");
      o.bulge_fraction_min = range[0];
      o.bulge_fraction_max = range[1];
    } else if (a == "--bd-radius-ratio") o.bd_radius_ratio = number_value(argc, argv, &i);
    else if (a == "--bd-misalignment") o.bd_misalignment_deg = number_value(argc, argv, &i);
    else if (a == "--bd-offset") o.bd_offset = number_value(argc, argv, &i);
    else if (a == "--e-sigma") o.e_sigma = number_value(argc, argv, &i);
    else if (a == "--e-max") o.e_max = number_value(argc, argv, &i);
    else if (a == "--centre-offset") o.centre_offset = number_value(argc, argv, &i);
    else if (a == "--shear-max") o.shear_max = number_value(argc, argv, &i);
    else if (a == "--shear") {
      const auto g = tools::number_pair(a, tools::option_value(argc, argv, &i), "G1,G2");
      o.fixed_shear = true;
      o.shear1 = g[0], o.shear2 = g[1];
    }
    else if (a == "--seed")
      o.seed = static_cast<std::uint64_t>(tools::integer_in(argc, argv, &i, 0, std::numeric_limits<long long>::max())); else throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede sim --help)");
  }
  if (out.empty()) throw std::invalid_argument("--out DIR is required (see stampede sim --help)");
  std::string why;
  if (!o.IsValid(&why)) throw std::invalid_argument(stampede::tools::with_flags(why, kGreat08Flags));
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) throw std::runtime_error("cannot create output directory '" + out + "': " + ec.message());
  if (!overwrite)
    for (int k = first_set; k < first_set + o.sets; ++k)
      for (const char* stem : {"set_", "truth_", "psf_"}) {
        io::refuse_to_replace(out + "/" + stem + std::to_string(k) + ".fits", overwrite);
      }
  const int n_threads = threads > 0 ? threads : tbb::info::default_concurrency();
  tbb::task_arena arena(n_threads);
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<Great08Simulator> sim;
  try {
    arena.execute([&] { sim = std::make_unique<Great08Simulator>(o); });
  } catch (const std::invalid_argument& e) {  // the simulator names fields
    throw std::invalid_argument(stampede::tools::with_flags(e.what(), kGreat08Flags));
  }
  const double setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::fprintf(stderr,
               "stampede sim great08: %d set(s) of %d x %d stamps (%d px), %s galaxies, Rgp/Rp %g, S/N %g%s; "
               "hlr %.4f (disc only) .. %.4f (bulge only) px; setup %.1f s on %d threads\n",
               o.sets, o.grid, o.grid, o.stamp_size, sim_galaxy_type_name(o.galaxy_type), o.size_ratio, o.snr,
               o.noise_free ? ", noise-free" : "", sim->half_light_radius(0.0), sim->half_light_radius(1.0), setup_s,
               n_threads);
  const std::string command_line = join_arguments(argc, argv);
  for (int k = first_set; k < first_set + o.sets; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    SimSet set;
    arena.execute([&] { set = sim->simulate_set(k); });
    io::write_great08_set(out, *sim, set, command_line, overwrite);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "  set %d: g = (%+.5f, %+.5f), %zu objects, %.1f s (%.1f ms per object)\n", k, set.shear1,
                 set.shear2, set.truth.size(), s, 1e3 * s / static_cast<double>(set.truth.size()));
  }
  std::printf("wrote %d set(s) to %s\n", o.sets, out.c_str());
  return 0;
}
