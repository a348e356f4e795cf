// A simulated MEDS tile on disk; see meds_simulation.hpp.
#include "app/meds_simulation.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <vector>

#include "engine/common/parallel_indices.hpp"
#include "io/durable_file.hpp"
#include "io/file_digest.hpp"
#include "io/fits_file.hpp"
#include "io/meds_writer.hpp"
#include "io/output_check.hpp"
#include "io/simulation_identity.hpp"

namespace stampede::app {

namespace {

constexpr long long kChunk = 64;

// Simulation workspaces not in use, shared by the chunks of one tile.
struct WorkspacePool {
  std::mutex mutex;
  std::vector<std::unique_ptr<MedsSimulator::Workspace>> free;
};

// A worker's workspace for one chunk: taken from the pool (or made) and given back at the end.
struct WorkspaceLease {
  WorkspaceLease(const MedsSimulator& sim, WorkspacePool& pool) : pool(pool) {
    {
      std::lock_guard<std::mutex> lock(pool.mutex);
      if (!pool.free.empty()) {
        workspace = std::move(pool.free.back());
        pool.free.pop_back();
      }
    }
    if (!workspace) workspace = sim.make_workspace();
  }
  WorkspaceLease(const WorkspaceLease&) = delete;
  WorkspaceLease& operator=(const WorkspaceLease&) = delete;
  ~WorkspaceLease() {
    std::lock_guard<std::mutex> lock(pool.mutex);
    pool.free.push_back(std::move(workspace));
  }
  WorkspacePool& pool;
  std::unique_ptr<MedsSimulator::Workspace> workspace;
};
constexpr double kRa0 = 45.0, kDec0 = 0.0;  // the tile's centre; objects on a line in RA

}  // namespace

std::string meds_simulation_id(const MedsSimOptions& o) {
  std::string text;
  auto add = [&](const char* name, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s=%.17g;", name, v);
    text += buf;
  };
  add("objects", o.objects), add("epochs", o.epochs), add("images", o.images), add("box_size", o.box_size);
  add("pixel_scale", o.pixel_scale), add("scale_jitter", o.scale_jitter), add("wcs_shear", o.wcs_shear);
  add("rotate", o.rotate), add("psf_beta", o.psf_beta), add("psf_fwhm_min", o.psf_fwhm_min);
  add("psf_fwhm_max", o.psf_fwhm_max), add("psf_e_max", o.psf_e_max), add("psf_size", o.psf_size);
  add("psf_cutouts", o.psf_cutouts), add("g1", o.g1), add("g2", o.g2), add("snr", o.snr);
  add("noise_sigma", o.noise_sigma), add("noise_free", o.noise_free), add("hlr_min", o.hlr_min);
  add("hlr_max", o.hlr_max), add("bulge_fraction_max", o.bulge_fraction_max), add("e_sigma", o.e_sigma);
  add("e_max", o.e_max), add("centre_offset", o.centre_offset), add("magzp", o.magzp);
  add("magzp_jitter", o.magzp_jitter), add("bad_column_fraction", o.bad_column_fraction);
  add("neighbour_fraction", o.neighbour_fraction), add("bands", o.bands);
  text += "seed=" + std::to_string(o.seed) + ";";  // 64 bits: beyond a double's 53
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(io::xxh64(text)));
  return hex;
}

void write_meds_simulation(const MedsSimOptions& options, const std::string& dir, bool overwrite,
                           const std::function<void(long long, long long)>& progress) {
  const MedsSimulator sim(options);
  namespace fs = std::filesystem;
  const std::string tile = (fs::path(dir) / "meds.fits").string(), truth_path = (fs::path(dir) / "truth.fits").string();
  for (const std::string& p : {tile, truth_path})
    if (fs::exists(p) && !overwrite) throw io::FileError("'" + p + "' exists (use --overwrite to replace it)");
  fs::create_directories(fs::path(dir) / "psfex");
  const int box = options.box_size, n = options.psf_size;

  // image_info: row 0 the coadd (no PSF: never fitted by default), then one row per source image.
  std::vector<io::MedsImageInfo> images(1);
  images[0].image_path = "coadd.fits";
  images[0].magzp = options.magzp;
  for (std::size_t i = 0; i < sim.images().size(); ++i) {
    const MedsSimImage& im = sim.images()[i];
    const std::string name = "psfex/image_" + std::to_string(i) + ".psf";
    io::write_psfex_constant((fs::path(dir) / name).string(), n, n, im.psf, im.psf_fwhm);
    io::MedsImageInfo info;
    info.image_path = "image_" + std::to_string(i) + ".fits";
    info.psf_path = name;
    info.image_id = static_cast<long long>(i) + 1;
    info.magzp = static_cast<float>(im.magzp);  // the file's float32
    images.push_back(info);
  }

  // The layout: every object's box and cutouts are known before any pixel is drawn.
  const double deg_per_arcsec = 1.0 / 3600;
  std::vector<io::MedsObjectLayout> layout(static_cast<std::size_t>(options.objects));
  for (long long i = 0; i < options.objects; ++i) {
    io::MedsObjectLayout& l = layout[static_cast<std::size_t>(i)];
    l.id = i + 1, l.number = i + 1, l.box_size = box;
    if (options.psf_cutouts) l.psf_size = n;
    l.ra = kRa0 + (i % 100) * 20 * deg_per_arcsec, l.dec = kDec0 + (i / 100) * 20 * deg_per_arcsec;
    l.cutouts.resize(static_cast<std::size_t>(options.epochs) + 1);
    const std::vector<MedsSimCutout> epochs = sim.epochs(i);
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      const MedsSimCutout& c = epochs[k];
      io::MedsCutout& mc = l.cutouts[k + 1];
      mc.file_id = c.image + 1;
      mc.orig_row = c.orig_row, mc.orig_col = c.orig_col;
      mc.orig_start_row = c.orig_start_row, mc.orig_start_col = c.orig_start_col;
      mc.cutout_row = c.cutout_row, mc.cutout_col = c.cutout_col;
      mc.dudrow = c.dudrow, mc.dudcol = c.dudcol, mc.dvdrow = c.dvdrow, mc.dvdcol = c.dvdcol;
      mc.psf_cutout_row = mc.psf_cutout_col = n / 2;  // the PSF's centre sample, as PSFEx's
    }
    l.cutouts[0] = l.cutouts[1];  // the coadd slot: the first epoch's geometry, blank pixels
    l.cutouts[0].file_id = 0;
  }
  const std::string id = meds_simulation_id(options);
  io::MedsWriter writer(tile, layout, images,
                        {io::MedsCutoutType::kWeight, io::MedsCutoutType::kSeg, io::MedsCutoutType::kBmask},
                        {{io::kSimulationIdKey, id}});
  // Workspaces outlive the chunks: a renderer and its prepared PSFs are made once per thread, not
  // once per chunk.
  WorkspacePool spare_workspaces;
  std::vector<MedsSimObject> chunk;
  const std::vector<double> empty(static_cast<std::size_t>(box) * box, 0.0), empty_psf(static_cast<std::size_t>(n) * n, 0.0);
  std::vector<double> seg(empty.size());
  // `index` repeats `id` under the name `stampede metrics` matches fit rows by (as in sim great08).
  io::FitsFile::OutputColumn cols[] = {{"id", true, {}},     {"index", true, {}},  {"number", true, {}}, {"pair", true, {}},
                                       {"e1_int", false, {}}, {"e2_int", false, {}}, {"e1_obs", false, {}},
                                       {"e2_obs", false, {}}, {"hlr", false, {}},    {"flux", false, {}},
                                       {"bulge_frac", false, {}}, {"u0", false, {}}, {"v0", false, {}},
                                       {"neighbour", true, {}}};
  for (long long first = 0; first < options.objects; first += kChunk) {
    const long long count = std::min<long long>(kChunk, options.objects - first);
    chunk.assign(static_cast<std::size_t>(count), MedsSimObject{});
    // Plain threads (parallel_indices), as every simulator loop: TSan sees their ordering in full.
    parallel_indices(
        count, 1, [&] { return WorkspaceLease(sim, spare_workspaces); },
        [&](WorkspaceLease& ws, long long k) { chunk[static_cast<std::size_t>(k)] = sim.simulate(first + k, *ws.workspace); });
    for (long long k = 0; k < count; ++k) {
      const MedsSimObject& o = chunk[static_cast<std::size_t>(k)];
      const long long row = first + k;
      for (io::MedsCutoutType t : {io::MedsCutoutType::kImage, io::MedsCutoutType::kWeight, io::MedsCutoutType::kSeg,
                                   io::MedsCutoutType::kBmask})
        writer.write_cutout(row, 0, t, empty);
      if (options.psf_cutouts) writer.write_psf_cutout(row, 0, empty_psf);
      for (std::size_t e = 0; e < o.cutouts.size(); ++e) {
        const MedsSimCutout& c = o.cutouts[e];
        const int icut = static_cast<int>(e) + 1;
        writer.write_cutout(row, icut, io::MedsCutoutType::kImage, c.pixels);
        writer.write_cutout(row, icut, io::MedsCutoutType::kWeight, c.weight);
        for (std::size_t i = 0; i < seg.size(); ++i)
          seg[i] = c.seg[i] == 1 ? static_cast<double>(row + 1) : c.seg[i] == 2 ? static_cast<double>(options.objects + row + 1) : 0.0;
        writer.write_cutout(row, icut, io::MedsCutoutType::kSeg, seg);
        writer.write_cutout(row, icut, io::MedsCutoutType::kBmask, c.bmask);
        if (options.psf_cutouts) writer.write_psf_cutout(row, icut, sim.images()[static_cast<std::size_t>(c.image)].psf);
      }
      const double values[] = {static_cast<double>(row + 1), static_cast<double>(row + 1), static_cast<double>(row + 1),
                               static_cast<double>(o.pair),
                               o.e1_int, o.e2_int, o.e1_obs, o.e2_obs, o.hlr, o.flux, o.bulge_frac, o.u0, o.v0,
                               o.neighbour ? 1.0 : 0.0};
      for (std::size_t c = 0; c < std::size(cols); ++c) cols[c].values.push_back(values[c]);
    }
    if (progress) progress(first + count, options.objects);
  }
  writer.finish();
  const std::string partial = truth_path + ".partial";
  {
    io::FitsFile truth = io::FitsFile::create(partial, true);
    truth.write_empty_image();
    truth.write_key(io::kSimulationIdKey, id, "the simulation (its tile's SIMID)");
    truth.write_key("SHEAR1", options.g1, "the constant shear g1, (u, v) frame");
    truth.write_key("SHEAR2", options.g2, "the constant shear g2");
    truth.write_key("NOISEFRE", options.noise_free ? 1LL : 0LL, "1: noise-free");
    truth.write_key("SNR", options.snr, "each object's S/N over its epochs");
    truth.write_key("MAGZP", options.magzp, "zero point of the flux column");
    if (options.bands > 1) {
      truth.write_key("BAND", static_cast<long long>(options.band), "this tile's band, 0-based");
      truth.write_key("NBANDS", static_cast<long long>(options.bands), "bands of the same galaxies");
    }
    truth.write_table("TRUTH", std::vector<io::FitsFile::OutputColumn>(std::begin(cols), std::end(cols)));
  }
  fs::rename(partial, truth_path);
}

}  // namespace stampede::app
