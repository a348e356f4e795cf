// One object's joint fit over bands; see multi_band_object_fit.hpp.
#include "app/multi_band_object_fit.hpp"

#include <algorithm>
#include <stdexcept>

#include "io/run_config.hpp"

namespace stampede::app {

void check_band_tiles(std::span<io::MedsFile* const> tiles) {
  if (tiles.empty()) return;
  io::MedsFile& first = *tiles[0];
  constexpr long long kChunk = 65536;  // ids compared a chunk at a time: memory bounded, any tile size
  std::vector<long long> a, b;
  for (std::size_t t = 1; t < tiles.size(); ++t) {
    io::MedsFile& other = *tiles[t];
    if (other.size() != first.size())
      throw io::ConfigError("--meds '" + other.path() + "' has " + std::to_string(other.size()) + " objects, --meds '" +
                            first.path() + "' " + std::to_string(first.size()) +
                            ": a multi-band run's tiles must list the same objects in the same order");
    for (long long begin = 0; begin < first.size(); begin += kChunk) {
      const long long n = std::min(kChunk, first.size() - begin);
      a.resize(static_cast<std::size_t>(n)), b.resize(static_cast<std::size_t>(n));
      first.read_ids(begin, a);
      other.read_ids(begin, b);
      const auto diff = std::mismatch(a.begin(), a.end(), b.begin());
      if (diff.first != a.end()) {
        const long long row = begin + (diff.first - a.begin());
        throw io::ConfigError("--meds '" + other.path() + "': object_data row " + std::to_string(row) + " has id " +
                              std::to_string(*diff.second) + ", --meds '" + first.path() + "' id " +
                              std::to_string(*diff.first) +
                              ": a multi-band run's tiles must list the same objects in the same order");
      }
    }
  }
}

MultiBandObjectFitter::MultiBandObjectFitter(std::span<io::MedsFile* const> tiles, const std::vector<std::string>& bands,
                                             const MedsFitOptions& options)
    : bands_(bands),
      model_(options.model),
      fitter_(options.model == MedsModel::kBulgeOrDisc ? single_component(options.fitter, Param::kBulgeA) : options.fitter) {
  if (tiles.size() != bands.size() || bands.empty())
    throw std::invalid_argument("MultiBandObjectFitter: " + std::to_string(tiles.size()) + " tiles for " +
                                std::to_string(bands.size()) + " bands");
  if (bands.size() > static_cast<std::size_t>(kMaxBands))
    throw std::invalid_argument(std::to_string(bands.size()) + " bands: at most " + std::to_string(kMaxBands));
  for (io::MedsFile* t : tiles) tiles_.push_back(std::make_unique<MedsObjectFitter>(*t, options));
  if (options.metacal.enabled && bands.size() > 1)
    metacal_ = std::make_unique<MultiEpochMetacalFitter>(options.fitter, options.metacal);
  if (options.model == MedsModel::kBulgeOrDisc)
    bulge_fitter_ = std::make_unique<MultiBandFitter>(single_component(options.fitter, Param::kDiscA));
}

MultiBandObjectFitter::~MultiBandObjectFitter() = default;

std::vector<std::string> MultiBandObjectFitter::psfex_files() const {
  std::vector<std::string> files;
  for (const auto& t : tiles_)
    for (const std::string& p : t->psfex_files())
      if (std::find(files.begin(), files.end(), p) == files.end()) files.push_back(p);
  return files;
}

MedsObjectResult MultiBandObjectFitter::fit(long long row) {
  const int n = static_cast<int>(tiles_.size());
  if (n == 1) {
    MedsObjectResult out = tiles_[0]->fit(row);
    BandFit& b = out.bands.emplace_back();
    b.n_epochs = out.n_epochs;
    b.bulge_a = out.fit.params[index(Param::kBulgeA)], b.disc_a = out.fit.params[index(Param::kDiscA)];
    b.bulge_flux = out.fit.bulge_flux, b.disc_flux = out.fit.disc_flux, b.flux = out.fit.flux, b.snr = out.fit.snr;
    return out;
  }
  MedsObjectResult out;
  out.bulge_or_disc = model_ == MedsModel::kBulgeOrDisc;
  out.bands.resize(static_cast<std::size_t>(n));
  epochs_.clear();
  metacal_epochs_.clear();
  std::uint32_t unusable = 0;  // why bands were left out
  long long pixels_total = 0, pixels_unmasked = 0;
  double psf_e1 = 0, psf_e2 = 0, psf_size = 0;
  for (int b = 0; b < n; ++b) {
    MedsObjectResult band;
    const bool usable = tiles_[static_cast<std::size_t>(b)]->collect(row, &band);
    if (b == 0) out.id = band.id, out.number = band.number, out.ra = band.ra, out.dec = band.dec;
    if (!band.problem.empty() && out.problem.empty()) out.problem = "band " + bands_[static_cast<std::size_t>(b)] + ": " + band.problem;
    if (!usable) {
      unusable |= band.flags & (kFlagNoUsableEpoch | kFlagTooMasked);
      out.flags |= band.flags & ~(kFlagNoUsableEpoch | kFlagTooMasked);
      continue;
    }
    out.flags |= band.flags;
    const MedsObjectFitter& tile = *tiles_[static_cast<std::size_t>(b)];
    for (std::size_t k = 0; k < tile.epochs().size(); ++k) {
      EpochData e = tile.epochs()[k];
      e.band = b;
      epochs_.push_back(e);
      if (metacal_) metacal_epochs_.push_back({e.pixels, e.weight, e.box_size, e.frame, &tile.epoch_psfs()[k], e.flux_scale, b});
    }
    pixels_total += band.pixels_total, pixels_unmasked += band.pixels_unmasked;
    psf_e1 += band.psf_e1 * band.n_epochs, psf_e2 += band.psf_e2 * band.n_epochs, psf_size += band.psf_size * band.n_epochs;
  }
  out.n_epochs = static_cast<int>(epochs_.size());
  out.pixels_total = pixels_total, out.pixels_unmasked = pixels_unmasked;
  if (epochs_.empty()) {
    out.flags |= unusable ? unusable : kFlagNoUsableEpoch;
    if (out.flags & kFlagPsfFailure) out.fit.status = FitStatus::kPsfFailure;
    return out;
  }
  out.masked_fraction = 1.0 - static_cast<double>(pixels_unmasked) / static_cast<double>(pixels_total);
  out.psf_e1 = psf_e1 / out.n_epochs, out.psf_e2 = psf_e2 / out.n_epochs, out.psf_size = psf_size / out.n_epochs;
  if (metacal_) {
    metacal_->fit(metacal_epochs_, out.id, kFlagMetacalFailure, &out.fit, &out.metacal, &out.flags, &out.problem, n,
                  &out.bands);
    out.gamma_fwhm = metacal_->gamma_fwhm();
    if (metacal_->epochs_used() > 0) out.n_epochs = metacal_->epochs_used();
    out.flags |= out.fit.flags;
    return out;
  }
  MultiBandFitResult r = fitter_.fit(epochs_, n, 0);
  if (bulge_fitter_) {
    // The PSFs were prepared by the tiles' renderers: the same kind, options and box sizes.
    MultiBandFitResult bulge = bulge_fitter_->fit(epochs_, n, 0);
    const bool disc_ok = IsUsable(r.fit.status), bulge_ok = IsUsable(bulge.fit.status);
    const bool take_bulge = bulge_ok && (!disc_ok || bulge.fit.likelihood > r.fit.likelihood);
    if (take_bulge) std::swap(r, bulge);
    out.is_bulge = take_bulge;
    out.other_likelihood = bulge.fit.likelihood;  // the loser's, after the swap
  }
  out.fit = r.fit;
  out.bands = std::move(r.bands);
  out.flags |= out.fit.flags;
  return out;
}

}  // namespace stampede::app
