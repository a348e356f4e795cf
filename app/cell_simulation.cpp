// Metadetection test cells on disk; see cell_simulation.hpp.
#include "app/cell_simulation.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "engine/common/parallel_indices.hpp"
#include "io/cell_image_writer.hpp"
#include "io/durable_file.hpp"
#include "io/meds_writer.hpp"
#include "io/output_check.hpp"
#include "io/result_columns.hpp"

namespace stampede::app {

namespace {

namespace fs = std::filesystem;

constexpr int kChunk = 16;                   // cells drawn per parallel step
constexpr double kRa0 = 45.0, kDec0 = 0.0;  // the notional tile's origin, degrees
constexpr double kMagzp = 30.0;

std::string sign_dir(const std::string& dir, int sign) { return sign == 0 ? dir : (fs::path(dir) / "minus").string(); }

std::string band_dir(const std::string& dir, int sign, const CellOutputOptions& out, int band) {
  const std::string s = sign_dir(dir, sign);
  return out.band_names.empty() ? s : (fs::path(s) / out.band_names[static_cast<std::size_t>(band)]).string();
}

std::string cell_path(const std::string& bdir, int cell) {
  char name[32];
  std::snprintf(name, sizeof name, "cell_%04d.fits", cell);
  return (fs::path(bdir) / name).string();
}

void check(const CellSimOptions& options, const CellOutputOptions& out) {
  if (out.cells < 1 || out.cells > 10000000)
    throw std::invalid_argument("cells " + std::to_string(out.cells) + ": must be in [1, 10000000]");
  if (!out.band_names.empty() && static_cast<int>(out.band_names.size()) != options.bands)
    throw std::invalid_argument("band_names: " + std::to_string(out.band_names.size()) + " names for " +
                                std::to_string(options.bands) + " bands");
  std::string why;
  if (!io::are_band_names(out.band_names, &why)) throw std::invalid_argument("band_names: " + why);
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
}

// An earlier run's cells in `bdir` that this one does not write (it has fewer cells, or no tile):
// left beside the new ones, a run over the directory would measure them as this simulation's.
void remove_stale_cells(const std::string& bdir, const CellOutputOptions& out) {
  for (const fs::directory_entry& e : fs::directory_iterator(bdir)) {
    const std::string name = e.path().filename().string();
    int index = -1;
    char tail = 0;
    const bool cell = std::sscanf(name.c_str(), "cell_%d.fits%c", &index, &tail) == 1 && cell_path("", index) == name;
    if ((cell && index >= out.cells) || (name == "cells_meds.fits" && !out.tile)) io::remove_if_present(e.path().string());
  }
}

// The cell tile's layout: object k = cell k, one cutout (the cell) on a notional square tile.
std::vector<io::MedsObjectLayout> tile_layout(const CellSimOptions& o, int cells) {
  const int per_row = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(cells))));
  const int step = o.size - 2 * o.buffer;  // adjacent cells overlap by their buffers
  const double centre = 0.5 * (o.size - 1), deg_per_px = o.pixel_scale / 3600;
  std::vector<io::MedsObjectLayout> layout(static_cast<std::size_t>(cells));
  for (int k = 0; k < cells; ++k) {
    io::MedsObjectLayout& l = layout[static_cast<std::size_t>(k)];
    l.id = k + 1, l.number = k + 1, l.box_size = o.size, l.psf_size = o.psf_size;
    io::MedsCutout c;
    c.file_id = 0;
    c.orig_start_row = static_cast<long long>(k / per_row) * step;
    c.orig_start_col = static_cast<long long>(k % per_row) * step;
    c.cutout_row = c.cutout_col = centre;
    c.orig_row = static_cast<double>(c.orig_start_row) + centre;
    c.orig_col = static_cast<double>(c.orig_start_col) + centre;
    c.dudcol = o.pixel_scale, c.dvdrow = o.pixel_scale;
    c.psf_cutout_row = c.psf_cutout_col = o.psf_size / 2;
    l.ra = kRa0 + c.orig_col * deg_per_px, l.dec = kDec0 + c.orig_row * deg_per_px;
    l.cutouts.push_back(c);
  }
  return layout;
}

}  // namespace

std::vector<std::string> cell_simulation_outputs(const CellSimOptions& options, const CellOutputOptions& out,
                                                 const std::string& dir) {
  std::vector<std::string> paths;
  for (int sign = 0; sign < (out.pair ? 2 : 1); ++sign) {
    for (int b = 0; b < options.bands; ++b) {
      const std::string bdir = band_dir(dir, sign, out, b);
      for (int k = 0; k < out.cells; ++k) paths.push_back(cell_path(bdir, k));
      if (out.tile) paths.push_back((fs::path(bdir) / "cells_meds.fits").string());
    }
    paths.push_back((fs::path(sign_dir(dir, sign)) / "truth.fits").string());
  }
  return paths;
}

void write_cell_simulation(const CellSimOptions& options, const CellOutputOptions& out, const std::string& dir,
                           const std::function<void(int, int)>& progress) {
  check(options, out);
  for (const std::string& p : cell_simulation_outputs(options, out, dir)) io::refuse_to_replace(p, out.overwrite);
  const CellSimulator sim(options);
  const int signs = out.pair ? 2 : 1, bands = options.bands;
  for (int sign = 0; sign < signs; ++sign)
    for (int b = 0; b < bands; ++b) {
      fs::create_directories(band_dir(dir, sign, out, b));
      if (out.overwrite) remove_stale_cells(band_dir(dir, sign, out, b), out);
    }

  // One tile per sign and band, its layout fixed up front.
  std::vector<std::unique_ptr<io::MedsWriter>> tiles;
  if (out.tile) {
    io::MedsImageInfo info;
    info.image_path = "cells";
    info.magzp = kMagzp;
    info.position_offset = 1;
    const std::vector<io::MedsObjectLayout> layout = tile_layout(options, out.cells);
    for (int sign = 0; sign < signs; ++sign)
      for (int b = 0; b < bands; ++b)
        tiles.push_back(std::make_unique<io::MedsWriter>(
            (fs::path(band_dir(dir, sign, out, b)) / "cells_meds.fits").string(), layout,
            std::vector<io::MedsImageInfo>{info},
            std::vector<io::MedsCutoutType>{io::MedsCutoutType::kWeight, io::MedsCutoutType::kSeg,
                                            io::MedsCutoutType::kBmask, io::MedsCutoutType::kNoise}));
  }

  // A workspace (its FFT plans) per concurrent worker, kept across the parallel steps: each step's
  // workers (at most the arena's concurrency, as parallel_indices starts) take slots 0, 1, ...
  std::vector<std::unique_ptr<CellSimulator::Workspace>> workspaces(
      static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency())));
  std::atomic<int> next_slot{0};
  const std::size_t npix = static_cast<std::size_t>(options.size) * options.size;
  const std::vector<double> zeros(npix, 0.0);
  std::vector<double> weight(npix);
  std::vector<std::vector<io::CellTruthRow>> truth(static_cast<std::size_t>(signs));
  std::vector<SimCell> chunk;
  for (int first = 0; first < out.cells; first += kChunk) {
    const int count = std::min(kChunk, out.cells - first);
    chunk.assign(static_cast<std::size_t>(count * signs), SimCell{});
    next_slot = 0;
    parallel_indices(count * signs, 1, [&] { return next_slot++; }, [&](int slot, long long k) {
      std::unique_ptr<CellSimulator::Workspace>& ws = workspaces[static_cast<std::size_t>(slot)];
      if (!ws) ws = sim.make_workspace();
      const int sign = static_cast<int>(k % signs);
      const double s = sign == 0 ? 1.0 : -1.0;
      chunk[static_cast<std::size_t>(k)] =
          sim.simulate(first + static_cast<int>(k / signs), s * options.g1, s * options.g2, *ws);
    });
    for (int k = 0; k < count * signs; ++k) {
      const SimCell& cell = chunk[static_cast<std::size_t>(k)];
      const int sign = k % signs;
      for (int b = 0; b < bands; ++b) {
        const std::string name = out.band_names.empty() ? "" : out.band_names[static_cast<std::size_t>(b)];
        io::write_cell_image(cell_path(band_dir(dir, sign, out, b), cell.index), sim, cell, b, name, out.overwrite);
        if (!out.tile) continue;
        io::MedsWriter& tile = *tiles[static_cast<std::size_t>(sign * bands + b)];
        const CellBand& band = sim.bands()[static_cast<std::size_t>(b)];
        const CellBandImage& img = cell.bands[static_cast<std::size_t>(b)];
        std::fill(weight.begin(), weight.end(), 1.0 / (band.noise_sigma * band.noise_sigma));
        tile.write_cutout(cell.index, 0, io::MedsCutoutType::kImage, img.image);
        tile.write_cutout(cell.index, 0, io::MedsCutoutType::kWeight, weight);
        tile.write_cutout(cell.index, 0, io::MedsCutoutType::kSeg, zeros);
        tile.write_cutout(cell.index, 0, io::MedsCutoutType::kBmask,
                          cell.defects.empty() ? zeros : cell.bmask(sim.options().size));
        tile.write_cutout(cell.index, 0, io::MedsCutoutType::kNoise, img.noise);
        tile.write_psf_cutout(cell.index, 0, band.psf);
      }
      for (const CellObject& o : cell.objects) truth[static_cast<std::size_t>(sign)].push_back({cell.index, o});
    }
    if (progress) progress(first + count, out.cells);
  }
  for (auto& t : tiles) t->finish();
  for (int sign = 0; sign < signs; ++sign) {
    const double s = sign == 0 ? 1.0 : -1.0;
    io::write_cell_truth((fs::path(sign_dir(dir, sign)) / "truth.fits").string(), sim, s * options.g1, s * options.g2,
                         truth[static_cast<std::size_t>(sign)], out.band_names, out.overwrite);
  }
}

}  // namespace stampede::app
