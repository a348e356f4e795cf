// `stampede ring`; see ring_command.hpp.
#include "tools/arguments.hpp"
#include "tools/ring_command.hpp"

#include <tbb/parallel_for.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/analysis/ring_study.hpp"
#include "engine/render/renderer_factory.hpp"
#include "tools/progress_printer.hpp"

namespace {

using namespace stampede;

void print_help() {
  std::printf(
      "usage: stampede ring --figure N [--csv FILE] [--renderer upsampled|exact]\n"
      "\n"
      "Noise-free ring tests (4 angles, shear +-(0.02, 0.01), |e| = 0.3 before shear; truth drawn at\n"
      "U1 = N_u = U2 = 25 with 8 px padding; fitted with the co-elliptical bulge + disc model) for the\n"
      "studies of the im3shape paper, section 4. Writes CSV (stdout, or FILE):\n"
      "  figure,panel,series,x,m1,m2,c1,c2,failed,fits,disc_radius\n"
      "\n"
      "  2  m vs U1 in {1,3,5,7} for N_u in {1,3,5,7}, U2 = 7: pure bulge and pure disc at\n"
      "     Rgp/Rp = 1.14 and 1.4; Moffat beta 3.5 FWHM 2.85 round; stamp 25\n"
      "  4  m vs the true Sersic index n (single component), sizes 1.2, 1.4, 1.6\n"
      "  5  m vs bulge - disc ellipticity difference (bulge |e| = 0.3), B/T 0.2, 0.5, 0.8, size 1.4\n"
      "  6  m vs the true bulge / disc radius ratio, B/T 0.5, sizes 1.2, 1.4, 1.6\n"
      "Figures 4-6: Moffat beta 3 FWHM 2.85 e = (0.03, 0.03), stamp 39, the fitter's defaults.\n"
      "--renderer: the fitter's renderer (default upsampled, the paper's; exact ignores U1, N_u, U2\n"
      "and its truth is the simulator's exact pixel integrals instead of the upsampled renderer's).\n"
      "FILE is opened before any work, so a bad path fails at once. Progress on stderr: redrawn\n"
      "on a terminal, else a line every 10 s.\n");
}

struct Row {
  std::string panel, series;
  double x = 0;
  RingStudyConfig config;
  double size = 1.4;  // Rgp/Rp to calibrate the disc radius for
  RingStudyResult result;
};

std::vector<Row> figure_rows(int figure) {
  std::vector<Row> rows;
  PsfModel round_psf, paper_psf;
  round_psf.moffat = {3.5, 2.85, 0.0, 0.0, 0.0};
  paper_psf.moffat = {3.0, 2.85, 0.03, 0.03, 0.0};
  auto base = [&](const PsfModel& psf, int stamp) {
    RingStudyConfig c;
    c.psf = psf;
    c.fit.render.stamp_size = stamp;
    return c;
  };
  char buf[64];
  switch (figure) {
    case 2:
      for (double bf : {1.0, 0.0})
        for (double size : {1.14, 1.4})
          for (int nu : {1, 3, 5, 7})
            for (int u1 : {1, 3, 5, 7}) {
              Row r;
              std::snprintf(buf, sizeof buf, "%s %.2f", bf > 0 ? "bulge" : "disc", size);
              r.panel = buf;
              r.series = "N_u=" + std::to_string(nu);
              r.x = u1;
              r.config = base(round_psf, 25);
              r.config.galaxy.bulge_fraction = bf;
              r.config.fit.render.upsampling = u1;
              r.config.fit.render.n_central_pixels_to_upsample = nu;
              r.config.fit.render.n_central_pixel_upsampling = 7;
              r.size = size;
              rows.push_back(r);
            }
      break;
    case 4:
      for (double size : {1.2, 1.4, 1.6})
        for (double n : {0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 6.0}) {
          Row r;
          r.panel = "sersic";
          std::snprintf(buf, sizeof buf, "size %.1f", size);
          r.series = buf;
          r.x = n;
          r.config = base(paper_psf, 39);
          r.config.galaxy.bulge_fraction = 1.0;
          r.config.galaxy.bulge_index = n;
          r.size = size;
          rows.push_back(r);
        }
      break;
    case 5:
      for (double bf : {0.2, 0.5, 0.8})
        for (int k = -5; k <= 5; ++k) {
          Row r;
          r.panel = "delta_e";
          std::snprintf(buf, sizeof buf, "B/T %.1f", bf);
          r.series = buf;
          r.x = 0.05 * k;
          r.config = base(paper_psf, 39);
          r.config.galaxy.bulge_fraction = bf;
          r.config.galaxy.delta_e = r.x;
          r.config.galaxy.disc_e = 0.3 - r.x;  // bulge |e| stays 0.3
          r.size = 1.4;
          rows.push_back(r);
        }
      break;
    case 6:
      for (double size : {1.2, 1.4, 1.6})
        for (double ratio : {0.5, 0.67, 0.8, 1.0, 1.25, 1.5, 2.0}) {
          Row r;
          r.panel = "radius_ratio";
          std::snprintf(buf, sizeof buf, "size %.1f", size);
          r.series = buf;
          r.x = ratio;
          r.config = base(paper_psf, 39);
          r.config.galaxy.radius_ratio = ratio;
          r.size = size;
          rows.push_back(r);
        }
      break;
    default:
      throw std::invalid_argument("--figure " + std::to_string(figure) + ": must be 2, 4, 5 or 6");
  }
  return rows;
}

}  // namespace

int run_ring_command(int argc, char** argv) {
  int figure = 0;
  std::string csv;
  RendererKind renderer = RendererKind::kUpsampled;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return tools::option_value(argc, argv, &i); };
    if (a == "--help" || a == "-h") {
      print_help();
      return 0;
    } else if (a == "--figure") {
      figure = static_cast<int>(tools::integer_in(argc, argv, &i, 0, 99));  // figure_rows names the valid ones
    } else if (a == "--csv") {
      csv = value();
    } else if (a == "--renderer") {
      const std::string v = value();
      if (!parse_renderer_kind(v, &renderer))
        throw std::invalid_argument("--renderer " + tools::quoted_value(v) + ": expected " + renderer_kind_names());
    } else {
      throw std::invalid_argument("unknown option " + tools::quoted_value(a) + " (see stampede ring --help)");
    }
  }
  std::vector<Row> rows = figure_rows(figure);
  for (Row& r : rows) {
    r.config.fit.renderer = renderer;
    // The exact fitter needs a truth more exact than the upsampled one's ~1e-4 (ring_study.hpp).
    if (renderer == RendererKind::kExact) r.config.truth = RingStudyConfig::Truth::kSimulator;
  }
  std::FILE* out = csv.empty() ? stdout : std::fopen(csv.c_str(), "w");
  if (!out) throw std::runtime_error("cannot write " + tools::quoted_value(csv) + ": " + std::strerror(errno));
  // Rows take seconds to minutes each and a figure up to tens of minutes: progress per row done.
  tools::ProgressPrinter printer(stderr, isatty(fileno(stderr)));
  std::mutex progress_mutex;
  std::size_t rows_done = 0;
  const auto start = std::chrono::steady_clock::now();
  auto row_done = [&] {
    const std::lock_guard<std::mutex> lock(progress_mutex);
    ++rows_done;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    char line[160];
    std::snprintf(line, sizeof line, "ring figure %d: %zu/%zu rows (%.1f%%), %.0f s, ETA %.0f s   ", figure, rows_done,
                  rows.size(), 100.0 * rows_done / rows.size(), seconds,
                  seconds / rows_done * (rows.size() - rows_done));
    printer.update(seconds, line);
  };
  tbb::parallel_for(std::size_t(0), rows.size(), [&](std::size_t i) {
    Row& row = rows[i];
    try {
      row.config.galaxy.disc_radius = disc_radius_for_size_ratio(row.config.galaxy, row.size, row.config.psf);
    } catch (const std::invalid_argument&) {
      row.config.galaxy.disc_radius = NAN;  // unreachable size: the row stays NaN
      row_done();
      return;
    }
    FftPlanCache plans(FftPlanning::kEstimate);
    row.result = run_ring_study(row.config, plans);
    row_done();
  });
  printer.finish();
  std::fprintf(out, "figure,panel,series,x,m1,m2,c1,c2,failed,fits,disc_radius\n");
  for (const Row& r : rows)
    std::fprintf(out, "%d,%s,%s,%.4g,%.6e,%.6e,%.6e,%.6e,%d,%d,%.5f\n", figure, r.panel.c_str(), r.series.c_str(), r.x,
                 r.result.m1, r.result.m2, r.result.c1, r.result.c2, r.result.failed, r.result.fits,
                 r.config.galaxy.disc_radius);
  if (out != stdout) std::fclose(out);
  return 0;
}
