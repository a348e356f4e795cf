// One MEDS object's joint fit; see meds_object_fit.hpp.
#include "app/meds_object_fit.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "engine/common/number_text.hpp"
#include "io/psfex_file.hpp"

namespace stampede::app {

namespace {
constexpr double kMaxZeroPointOffset = 25;  // magnitudes: a factor 1e10 in flux
}  // namespace

void apply_uberseg(std::span<const double> seg, int box_size, std::int64_t number, std::span<double> weight) {
  struct Labelled {
    int x, y;
    bool own;
  };
  std::vector<Labelled> labelled;
  for (int y = 0; y < box_size; ++y)
    for (int x = 0; x < box_size; ++x) {
      const double v = seg[static_cast<std::size_t>(y) * box_size + x];
      if (v != 0) labelled.push_back({x, y, v == static_cast<double>(number)});
    }
  if (labelled.empty()) return;
  for (int y = 0; y < box_size; ++y)
    for (int x = 0; x < box_size; ++x) {
      long best_own = -1, best_other = -1;
      for (const Labelled& l : labelled) {
        const long d = static_cast<long>(l.x - x) * (l.x - x) + static_cast<long>(l.y - y) * (l.y - y);
        long& best = l.own ? best_own : best_other;
        if (best < 0 || d < best) best = d;
      }
      if (best_other >= 0 && (best_own < 0 || best_other < best_own)) weight[static_cast<std::size_t>(y) * box_size + x] = 0;
    }
}

namespace {

// A fit renders each cutout on a Fourier grid of about (box + 57)^2 complex values per renderer and
// derivative: beyond this a corrupt box size would cost gigabytes; DES and LSST boxes are <= 256.
constexpr long long kMaxFitBoxSize = 1024;

}  // namespace

FitterOptions single_component(FitterOptions o, Param zero) {
  o.params[zero].free = false;
  o.params[zero].start = 0;
  return o;
}

MedsObjectFitter::MedsObjectFitter(io::MedsFile& meds, const MedsFitOptions& options)
    : meds_(meds),
      options_(options),
      fitter_(options.model == MedsModel::kBulgeOrDisc ? single_component(options.fitter, Param::kBulgeA) : options.fitter) {
  if (options.model == MedsModel::kBulgeOrDisc && options.metacal.enabled)
    throw std::invalid_argument("option 'meds_model' = 'bord' with metacal = true: metacal fits metacal_model (bd, exp "
                                "or gauss)");
  if (options.model == MedsModel::kBulgeOrDisc)
    bulge_fitter_ = std::make_unique<MultiEpochFitter>(single_component(options.fitter, Param::kDiscA));
  if (options.metacal.enabled) metacal_ = std::make_unique<MultiEpochMetacalFitter>(options.fitter, options.metacal);
  source_ = options.psf;
  if (source_ == io::MedsPsfSource::kAuto)
    source_ = meds.has_psf_cutouts() ? io::MedsPsfSource::kCutouts : io::MedsPsfSource::kPsfex;
  if (source_ == io::MedsPsfSource::kCutouts && !meds.has_psf_cutouts())
    throw std::invalid_argument("option 'meds_psf' = 'cutouts': " + meds.psf_cutouts_problem());
  models_.resize(meds.images().size());
  model_errors_.resize(meds.images().size());
  if (options_.psf_dir.empty()) options_.psf_dir = std::filesystem::path(meds.path()).parent_path().string();
}

MedsObjectFitter::~MedsObjectFitter() = default;

std::filesystem::path MedsObjectFitter::psfex_file(const std::string& psf_path) const {
  const std::filesystem::path name(psf_path);
  return name.is_absolute() ? name : std::filesystem::path(options_.psf_dir.empty() ? "." : options_.psf_dir) / name;
}

std::vector<std::string> MedsObjectFitter::psfex_files() const {
  std::vector<std::string> files;
  if (source_ != io::MedsPsfSource::kPsfex) return files;
  for (const io::MedsImageInfo& info : meds_.images()) {
    if (info.psf_path.empty()) continue;
    const std::string p = psfex_file(info.psf_path).lexically_normal().string();
    if (std::find(files.begin(), files.end(), p) == files.end()) files.push_back(p);
  }
  return files;
}

const PsfexModel* MedsObjectFitter::psfex(long long file_id, std::string* problem) {
  const std::size_t i = static_cast<std::size_t>(file_id);
  if (!models_[i] && model_errors_[i].empty()) {
    const std::string& name = meds_.images()[i].psf_path;
    if (name.empty()) {
      model_errors_[i] = meds_.path() + ": image_info row " + std::to_string(file_id) + " names no PSFEx model (psf_path)";
    } else {
      const std::filesystem::path path = psfex_file(name);
      try {
        models_[i] = io::read_psfex_model(path.string());
      } catch (const std::runtime_error& e) {
        model_errors_[i] = e.what();
      }
    }
  }
  if (!models_[i]) {
    *problem = model_errors_[i];
    return nullptr;
  }
  return &*models_[i];
}

std::shared_ptr<const PreparedPsf> MedsObjectFitter::cutout_psf(const io::MedsObject& o, int k,
                                                                 std::shared_ptr<const PsfImage>* used, std::string* why) {
  const io::MedsCutout& c = o.cutouts[static_cast<std::size_t>(k)];
  const int box = static_cast<int>(o.box_size);
  std::shared_ptr<const PsfImage> image;
  switch (source_) {
    case io::MedsPsfSource::kOptions: {
      std::shared_ptr<const PreparedPsf>& p = options_psf_[box];
      if (!p) p = fitter_.renderer_for(box).prepare_psf(options_.psf_model, why);
      return p;
    }
    case io::MedsPsfSource::kCutouts: {
      if (!c.psf_problem.empty()) {
        *why = c.psf_problem;
        return nullptr;
      }
      auto img = std::make_shared<PsfImage>();
      img->nx = static_cast<int>(c.psf_cols), img->ny = static_cast<int>(c.psf_rows);
      img->pixels.resize(static_cast<std::size_t>(c.psf_rows * c.psf_cols));
      meds_.read_psf_cutout(o, k, img->pixels);
      img->centre_x = c.psf_cutout_col, img->centre_y = c.psf_cutout_row;
      img->oversampling = 1;
      img->pixel_integrated = true;
      image = std::move(img);
      break;
    }
    default: {
      // The source image's PSFEx model at the object's position there (1-based X_IMAGE).
      const PsfexModel* model = psfex(c.file_id, why);
      if (model) image = model->image_at(c.orig_col + 1, c.orig_row + 1, why);
      break;
    }
  }
  *used = image;
  if (!image) return nullptr;
  return fitter_.renderer_for(box).prepare_psf(PsfModel::Image(image), why);
}

bool MedsObjectFitter::collect(long long row, MedsObjectResult* result) {
  MedsObjectResult& out = *result;
  out.bulge_or_disc = options_.model == MedsModel::kBulgeOrDisc;
  last_psfs_.clear();
  epochs_.clear();
  epoch_psfs_.clear();
  const io::MedsObject o = meds_.object(row);
  out.id = o.id, out.number = o.number, out.ra = o.ra, out.dec = o.dec;
  auto note = [&](const std::string& why) {
    if (out.problem.empty()) out.problem = why;
  };
  if (!o.problem.empty()) {
    note(o.problem);
    out.flags |= kFlagNoUsableEpoch;
    return false;
  }
  if (o.box_size > kMaxFitBoxSize) {
    note(meds_.path() + ": object " + std::to_string(row) + ": column 'box_size' = " + std::to_string(o.box_size) +
         " is larger than a galaxy fit takes (" + std::to_string(kMaxFitBoxSize) + ")");
    out.flags |= kFlagNoUsableEpoch;
    return false;
  }
  const int box = static_cast<int>(o.box_size);
  const std::size_t npix = static_cast<std::size_t>(box) * box;
  std::vector<EpochData>& epochs = epochs_;
  long long pixels_total = 0, pixels_unmasked = 0;
  double psf_e1 = 0, psf_e2 = 0, psf_size = 0;
  const int first = options_.fit_coadd ? 0 : 1, last = options_.fit_coadd ? 1 : static_cast<int>(o.cutouts.size());
  if (pixels_.size() < o.cutouts.size()) pixels_.resize(o.cutouts.size()), weights_.resize(o.cutouts.size());
  for (int k = first; k < last && k < static_cast<int>(o.cutouts.size()); ++k) {
    const io::MedsCutout& c = o.cutouts[static_cast<std::size_t>(k)];
    if (!c.problem.empty()) {
      note(c.problem);
      continue;
    }
    std::vector<double>& pixels = pixels_[static_cast<std::size_t>(k)];
    std::vector<double>& weight = weights_[static_cast<std::size_t>(k)];
    pixels.resize(npix);
    weight.resize(npix);
    meds_.read_cutout(o, k, io::MedsCutoutType::kImage, pixels);
    if (meds_.has(io::MedsCutoutType::kWeight))
      meds_.read_cutout(o, k, io::MedsCutoutType::kWeight, weight);
    else
      std::fill(weight.begin(), weight.end(), 1.0);
    if (meds_.has(io::MedsCutoutType::kBmask)) {
      bmask_.resize(npix);
      meds_.read_cutout(o, k, io::MedsCutoutType::kBmask, bmask_);
      for (std::size_t i = 0; i < npix; ++i)
        if (static_cast<std::uint32_t>(static_cast<std::int64_t>(bmask_[i])) & options_.bmask_bits) weight[i] = 0;
    }
    if (options_.uberseg && meds_.has(io::MedsCutoutType::kSeg)) {
      seg_.resize(npix);
      meds_.read_cutout(o, k, io::MedsCutoutType::kSeg, seg_);
      apply_uberseg(seg_, box, o.number, weight);
    }
    for (std::size_t i = 0; i < npix; ++i)
      if (!std::isfinite(pixels[i]) || !(weight[i] >= 0) || !std::isfinite(weight[i])) weight[i] = 0, pixels[i] = 0;
    long long unmasked = 0;
    for (double w : weight) unmasked += w > 0;
    pixels_total += static_cast<long long>(npix);
    pixels_unmasked += unmasked;
    if (unmasked == 0) {
      note(meds_.path() + ": object " + std::to_string(row) + ", cutout " + std::to_string(k) + ": every pixel masked");
      continue;
    }
    std::string why;
    std::shared_ptr<const PsfImage> image;
    const std::shared_ptr<const PreparedPsf> prepared = cutout_psf(o, k, &image, &why);
    if (!prepared) {
      note(meds_.path() + ": object " + std::to_string(row) + ", cutout " + std::to_string(k) + ": PSF: " + why);
      out.flags |= kFlagPsfFailure;
      continue;
    }
    const io::MedsImageInfo& info = meds_.images()[static_cast<std::size_t>(c.file_id)];
    // A zero point more than kMaxZeroPointOffset magnitudes from the reference (a NaN, 1e30, -100)
    // is a broken record, not a calibration: the cutout would weigh nothing or everything.
    if (!std::isfinite(info.magzp) || std::abs(info.magzp - options_.magzp_ref) > kMaxZeroPointOffset) {
      note(meds_.path() + ": image_info row " + std::to_string(c.file_id) + ": magzp = " + number_text(info.magzp) +
           " is not a usable zero point (more than " + number_text(kMaxZeroPointOffset) +
           " mag from meds_magzp_ref = " + number_text(options_.magzp_ref) + "); object " + std::to_string(row) +
           ", cutout " + std::to_string(k) + " dropped");
      out.flags |= kFlagBadZeroPoint;
      continue;
    }
    const double scale = std::pow(10.0, 0.4 * (info.magzp - options_.magzp_ref));
    epochs.push_back({pixels, weight, box, PixelFrame::from_meds(c.dudrow, c.dudcol, c.dvdrow, c.dvdcol, c.cutout_row, c.cutout_col),
                      prepared, scale});
    last_psfs_.push_back(image);
    if (metacal_) epoch_psfs_.push_back(image ? PsfModel::Image(image) : options_.psf_model);
    const double xx = prepared->xx(), xy = prepared->xy(), yy = prepared->yy();
    psf_e1 += (xx - yy) / (xx + yy), psf_e2 += 2 * xy / (xx + yy), psf_size += std::sqrt(0.5 * (xx + yy));
  }
  out.n_epochs = static_cast<int>(epochs.size());
  out.masked_fraction = pixels_total > 0 ? 1.0 - static_cast<double>(pixels_unmasked) / pixels_total : NAN;
  if (epochs.empty()) {
    out.flags |= kFlagNoUsableEpoch;
    if (out.flags & kFlagPsfFailure) out.fit.status = FitStatus::kPsfFailure;
    return false;
  }
  if (pixels_unmasked < pixels_total) out.flags |= kFlagMaskedPixels;
  out.psf_e1 = psf_e1 / out.n_epochs, out.psf_e2 = psf_e2 / out.n_epochs, out.psf_size = psf_size / out.n_epochs;
  out.pixels_total = pixels_total, out.pixels_unmasked = pixels_unmasked;
  if (1.0 - out.masked_fraction < options_.min_unmasked_fraction) {
    out.flags |= kFlagTooMasked;
    return false;
  }
  return true;
}

MedsObjectResult MedsObjectFitter::fit(long long row) {
  MedsObjectResult out;
  if (!collect(row, &out)) return out;
  const std::vector<EpochData>& epochs = epochs_;
  if (metacal_) {
    metacal_epochs_.clear();
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      const EpochData& e = epochs[k];
      metacal_epochs_.push_back({e.pixels, e.weight, e.box_size, e.frame, &epoch_psfs_[k], e.flux_scale});
    }
    metacal_->fit(metacal_epochs_, out.id, kFlagMetacalFailure, &out.fit, &out.metacal, &out.flags, &out.problem);
    out.gamma_fwhm = metacal_->gamma_fwhm();
    if (metacal_->epochs_used() > 0) out.n_epochs = metacal_->epochs_used();
    out.flags |= out.fit.flags;
    return out;
  }
  out.fit = fitter_.fit(epochs, 0);
  if (bulge_fitter_) {
    // The PSFs were prepared by fitter_'s renderers: the same kind, options and box size.
    FitResult bulge = bulge_fitter_->fit(epochs, 0);
    const bool disc_ok = IsUsable(out.fit.status), bulge_ok = IsUsable(bulge.status);
    const bool take_bulge = bulge_ok && (!disc_ok || bulge.likelihood > out.fit.likelihood);
    if (take_bulge) std::swap(out.fit, bulge);
    out.is_bulge = take_bulge;
    out.other_likelihood = bulge.likelihood;  // the loser's, after the swap
  }
  out.flags |= out.fit.flags;
  return out;
}

}  // namespace stampede::app
