// Metadetection of one cell; see cell_measurer.hpp.
#include "engine/metadetect/cell_measurer.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_fitter.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_type.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
#include "kernels/mask_fill.hpp"
#include "engine/model/pixelated_psf.hpp"
#include "kernels/fourier_profiles.hpp"
#include "kernels/weighted_moments.hpp"

namespace stampede {
namespace {

// Pixels of zeros on each side of a cell on the metacal grid. The operations are periodic: a
// galaxy's light at one edge reaches the opposite edge's pixels through the filters' real-space
// kernel (about the reconvolution PSF's width), here >= 32 pixels of padding plus the buffer away
// from any measured pixel; the 2x padding a postage stamp needs (its own light must not wrap onto
// it) would cost 2.5x more at a cell's size (docs/metadetect.md).
constexpr int kCellMargin = 16;

// Per-object metacal's stamp side (the postage stamps of `stampede fit --metacal`'s size class).
constexpr int kPerObjectStamp = 49;

}  // namespace

CellMeasurer::CellMeasurer(const MetadetectOptions& options, FftPlanning planning)
    : options_(options), planning_(planning), detector_(options.detection) {
  if (is_model_fit(options.measurement))
    // `stampede fit --metacal`'s fit of metacal_model gauss, exp or bd (default fit options otherwise).
    fitter_ = std::make_unique<ObjectFitter>(
        metacal_fit_options(FitterOptions{}, options.measurement == MetadetectMeasurement::kExp     ? MetacalModel::kExponential
                                             : options.measurement == MetadetectMeasurement::kGauss ? MetacalModel::kGaussian
                                                                                                     : MetacalModel::kBulgeDisc),
        planning);
}

namespace {

// Image PSFs compare by their samples: every file of a run may carry its own copy of one PSF, and
// the filters cost as much as a cell's images.
bool same_psf(const PsfModel& a, const PsfModel& b) {
  if (a == b) return true;
  if (a.kind != PsfKind::kImage || b.kind != PsfKind::kImage || !a.image || !b.image) return false;
  const PsfImage &p = *a.image, &q = *b.image;
  return p.nx == q.nx && p.ny == q.ny && p.pixels == q.pixels && p.oversampling == q.oversampling &&
         p.pixel_integrated == q.pixel_integrated &&
         (p.centre_x == q.centre_x || (std::isnan(p.centre_x) && std::isnan(q.centre_x))) &&
         (p.centre_y == q.centre_y || (std::isnan(p.centre_y) && std::isnan(q.centre_y)));
}

// Band b's fixnoise stream: the first band's is the one-band cell's (so that one band gives its
// rows), the others' are keyed by the band as the multi-epoch metacal keys its cutouts.
RandomStream fixnoise_stream(std::uint64_t seed, long long cell, std::size_t band) {
  const auto c = static_cast<std::uint64_t>(cell);
  return band == 0 ? RandomStream({seed, c, kFixnoisePurpose}) : RandomStream({seed, c, kFixnoisePurpose, band});
}

}  // namespace

bool CellMeasurer::prepare_psf(double pixel_scale, std::string* problem) {
  bool same = have_psf_ && pixel_scale == psf_scale_ && psfs_.size() == bands_.size();
  for (std::size_t b = 0; same && b < bands_.size(); ++b) same = same_psf(*bands_[b].image.psf_model, psfs_[b]);
  if (same) {
    // A cell with the PSF that failed last fails alike, and says why (every failed cell is counted).
    if (filters_.empty()) *problem = psf_problem_;
    return !filters_.empty();
  }
  if (!prepare_new_psf(pixel_scale, problem)) {
    filters_.clear();
    psf_problem_ = *problem;
    return false;
  }
  return true;
}

bool CellMeasurer::prepare_new_psf(double pixel_scale, std::string* problem) {
  have_psf_ = true;
  psfs_.clear();
  for (const MetadetectBand& b : bands_) psfs_.push_back(*b.image.psf_model);
  psf_scale_ = pixel_scale;
  filters_.clear();
  MetacalOptions metacal;
  metacal.enabled = true;
  metacal.step = options_.step;
  metacal.psf_dilation = options_.psf_dilation;
  metacal.reconvolution = options_.reconvolution;
  std::string why;
  if (bands_.size() == 1) {
    auto f = reconvolution_filters(psfs_[0], metacal, images_set_->period(), &why);
    if (!f) {
      *problem = "no metacal reconvolution PSF serves this PSF: " + why;
      return false;
    }
    filters_.push_back(std::move(f));
  } else {
    // One Gamma for the shape bands, so that their images share their PSF and their moments
    // combine: the widest they need (the cell's pixels are every band's frame). The other bands
    // (detection, fluxes) the widest every band needs: a shape band's Gamma may not serve them.
    const auto gamma_of = [&](std::uint32_t mask, const char* which, SkyReconvolution* gamma) {
      std::vector<MetacalEpochPsf> epochs;
      for (std::size_t b = 0; b < psfs_.size(); ++b)
        if (mask >> b & 1u) epochs.push_back({&psfs_[b], PixelFrame{}, images_set_->period()});
      if (sky_reconvolution(epochs, metacal, gamma, &why)) return true;
      *problem = std::string("no metacal reconvolution PSF serves ") + which + ": " + why;
      return false;
    };
    const std::uint32_t all = (1u << bands_.size()) - 1;
    SkyReconvolution shapes, every;
    if (!gamma_of(shear_mask_, shear_mask_ == all ? "every band's PSF" : "the shape bands' PSFs", &shapes)) return false;
    if (shear_mask_ != all && !gamma_of(all, "every band's PSF", &every)) return false;
    filters_.assign(bands_.size(), nullptr);
    for (std::size_t b = 0, k = 0; b < bands_.size(); ++b)
      filters_[b] = shear_mask_ >> b & 1u ? shapes.filters[k++] : every.filters[b];
  }
  weight_fwhm_px_ = options_.weight_fwhm_arcsec() / pixel_scale;
  // The weight is drawn on a stamp of 8 FWHM: narrower than half a pixel it samples nothing, wider
  // than half the cell it weighs the neighbours and the cell's edge (and costs the square of it).
  const int cell_size = images_set_->stamp_size();
  if (!(weight_fwhm_px_ >= 0.5 && weight_fwhm_px_ <= 0.5 * cell_size)) {
    char b[200];
    std::snprintf(b, sizeof b, "weight_fwhm = %g arcsec is %g pixels of %g arcsec: must be in [0.5, %g] (half the cell)",
                  options_.weight_fwhm_arcsec(), weight_fwhm_px_, pixel_scale, 0.5 * cell_size);
    *problem = b;
    return false;
  }
  psf_k_[0].clear(), psf_k_[1].clear();
  fit_psfs_.clear();
  // The point source's T under the same weight, as the detections' T is measured. pgauss's T_ratio
  // divides by the same (ngmix measures the PSF with the pre-PSF weight but no PSF to remove: its
  // weighted T): a pre-PSF T over the reconvolved point source's, so that T_ratio > 0.5 (DES Y6's
  // pgauss cut) keeps objects resolved relative to Gamma.
  const int n = 2 * static_cast<int>(std::ceil(4 * weight_fwhm_px_)) + 1;
  // The reconvolution PSF convolved with the pixel: what a point source is in the metacal images.
  std::vector<double> image(static_cast<std::size_t>(n) * n);
  pixelated_psf(filters_[shape_band_]->reconvolution(), n, 5, image);
  std::vector<double> scratch(2 * static_cast<std::size_t>(n));
  const kernels::WeightedMoments m = kernels::weighted_moments(image, n, weight_fwhm_px_, 0.0, scratch);
  if (!m.valid) {
    filters_.clear();
    *problem = "the reconvolution PSF's weighted moments are not valid";
    return false;
  }
  psf_t_ = m.t;
  psf_rec_e1_ = m.e1, psf_rec_e2_ = m.e2;
  // The original PSFs (the shape bands', their moments averaged) under the same weight, for
  // PSF-leakage tests: each band's PSF image as given (a pixel-integrated sampling), else drawn.
  psf_orig_e1_ = psf_orig_e2_ = psf_orig_t_ = 0;
  int shape_bands = 0;
  for (std::size_t b = 0; b < psfs_.size(); ++b) {
    if (!(shear_mask_ >> b & 1u)) continue;
    const PsfModel& p = psfs_[b];
    kernels::WeightedMoments pm;
    if (p.image) {
      std::vector<double> s(2 * static_cast<std::size_t>(std::max(p.image->nx, p.image->ny)));
      if (p.image->nx == p.image->ny)
        pm = kernels::weighted_moments(p.image->pixels, p.image->nx, weight_fwhm_px_, 0.0, s);
    } else {
      pixelated_psf(p, n, 5, image);
      pm = kernels::weighted_moments(image, n, weight_fwhm_px_, 0.0, scratch);
    }
    if (!pm.valid) {
      psf_orig_e1_ = psf_orig_e2_ = psf_orig_t_ = NAN;
      break;
    }
    psf_orig_e1_ += pm.e1, psf_orig_e2_ += pm.e2, psf_orig_t_ += pm.t, ++shape_bands;
  }
  if (shape_bands > 0) psf_orig_e1_ /= shape_bands, psf_orig_e2_ /= shape_bands, psf_orig_t_ /= shape_bands;
  if (options_.per_object_metacal) {
    if (!stamp_set_) stamp_set_ = std::make_unique<MetacalImageSet>(kPerObjectStamp, planning_);
    stamp_filters_ = reconvolution_filters(psfs_[0], metacal, stamp_set_->period(), &why);
    if (!stamp_filters_) {
      filters_.clear();
      *problem = "no metacal reconvolution PSF serves this PSF on a stamp: " + why;
      return false;
    }
  }
  return true;
}

bool CellMeasurer::measure(const MetadetectCell& cell, std::vector<MetadetectRow>* rows, std::string* problem) {
  auto fail = [&](const std::string& why) {
    MetadetectRow r;
    r.cell = cell.index;
    r.shear_type = static_cast<int>(MetacalType::kNoshear);
    r.flags = kMetadetectCellFailed;
    rows->push_back(r);
    *problem = why;
    return false;
  };
  if (cell.bands.empty()) return fail("no bands");
  if (cell.bands.size() > static_cast<std::size_t>(kMaxMetadetectBands))
    return fail("more than " + std::to_string(kMaxMetadetectBands) + " bands");
  for (std::size_t b = 1; b < cell.bands.size(); ++b)
    if (cell.bands[b].image.box_size != cell.size())
      return fail("band " + std::to_string(b) + " is " + std::to_string(cell.bands[b].image.box_size) +
                  " pixels, the cell " + std::to_string(cell.size()));
  if (!images_set_ || images_set_->stamp_size() != cell.size())
    images_set_ = std::make_unique<MetacalImageSet>(
        cell.size(), planning_, MetacalImager::padded_size(cell.size(), kCellMargin),
        options_.double_images ? MetacalImageSet::Precision::kDouble : MetacalImageSet::Precision::kSingle,
        MetacalImageSet::NoiseDraw::kPairs),
    have_psf_ = false;
  if (options_.per_object_metacal && cell.bands.size() > 1)
    return fail("per-object metacal measures one band");
  if (fitter_ && cell.bands.size() > 1)
    return fail(std::string("measurement ") + metadetect_measurement_name(options_.measurement) +
                " fits one band (wmom and pgauss measure several)");
  bands_ = cell.bands;
  {
    const std::uint32_t all = (1u << bands_.size()) - 1;
    for (const auto& [field, mask] : {std::pair{"detect_bands", options_.detect_bands},
                                      std::pair{"shear_bands", options_.shear_bands}})
      if (mask & ~all)
        return fail(std::string(field) + " names band " + std::to_string(std::countr_zero(mask & ~all)) +
                    " but the cell has " + std::to_string(bands_.size()) + " band" + (bands_.size() == 1 ? "" : "s"));
    detect_mask_ = options_.detect_bands ? options_.detect_bands : all;
    shear_mask_ = options_.shear_bands ? options_.shear_bands : all;
    shape_band_ = static_cast<std::size_t>(std::countr_zero(shear_mask_));
  }
  for (std::size_t b = 0; b < bands_.size(); ++b)
    if (!bands_[b].image.psf_model) return fail(b == 0 ? std::string("no PSF") : "no PSF for band " + std::to_string(b));
  cell_masked_ = !cell.stars.empty();
  for (const MetadetectBand& b : bands_)
    cell_masked_ =
        cell_masked_ || std::any_of(b.image.weight.begin(), b.image.weight.end(), [](double w) { return !(w > 0); });
  if (!prepare_psf(cell.pixel_scale, problem)) return fail(*problem);
  const std::size_t npix = static_cast<std::size_t>(cell.size()) * cell.size();
  if (cell_masked_) {
    // One mask for the cell: a pixel any band masks, and (symmetrise_mask) its quarter turns.
    mask_.assign(npix, 0);
    for (const MetadetectBand& b : bands_)
      for (std::size_t p = 0; p < b.image.weight.size(); ++p)
        if (!(b.image.weight[p] > 0)) mask_[p] = 1;
    const int s = cell.size();
    for (const StarDisc& star : cell.stars) {
      const int ylo = std::max(0, static_cast<int>(std::floor(star.y - star.radius))),
                yhi = std::min(s - 1, static_cast<int>(std::ceil(star.y + star.radius)));
      const int xlo = std::max(0, static_cast<int>(std::floor(star.x - star.radius))),
                xhi = std::min(s - 1, static_cast<int>(std::ceil(star.x + star.radius)));
      for (int y = ylo; y <= yhi; ++y)
        for (int x = xlo; x <= xhi; ++x)
          if (star.holds(x, y)) mask_[static_cast<std::size_t>(y) * s + x] = 1;
    }
    if (options_.symmetrise_mask) kernels::symmetrise_mask(mask_, cell.size(), &mask_turned_);
  }
  MetacalOptions metacal;
  metacal.enabled = true;
  metacal.step = options_.step;
  metacal.fixnoise = options_.fixnoise;
  if (images_.size() < bands_.size()) images_.resize(bands_.size());
  variances_.assign(bands_.size(), 0.0);
  for (std::size_t b = 0; b < bands_.size(); ++b) {
    images_[b].resize(kNumMetacalTypes * npix);
    const Observation& image = bands_[b].image;
    std::span<const double> pixels = image.pixels, weight = image.weight, noise = bands_[b].noise;
    if (cell_masked_) prepare_masked(cell.size(), &pixels, &weight, &noise);
    images_set_->make(pixels, weight, WeightKind::kInverseVariance, 0.0, *filters_[b], metacal,
                      fixnoise_stream(options_.seed, cell.index, b), images_[b], &variances_[b], 1.0, nullptr, noise);
    if (!(variances_[b] > 0) || !std::isfinite(variances_[b]))
      return fail(bands_.size() == 1 ? std::string("the cell's weights give no positive finite noise variance")
                                     : "band " + std::to_string(b) + "'s weights give no positive finite noise variance");
  }
  // The detection bands are detected on their sum weighted by each band's inverse noise variance,
  // normalised (sum w_b I_b / sum w_b): its noise variance is 1 / sum w_b for independent noise.
  // One detection band: its image as it is.
  const bool one_detection_band = std::popcount(detect_mask_) == 1;
  const std::size_t detection_band = static_cast<std::size_t>(std::countr_zero(detect_mask_));
  double detection_variance = variances_[detection_band];
  if (!one_detection_band) {
    double wsum = 0;
    for (std::size_t b = 0; b < bands_.size(); ++b)
      if (detect_mask_ >> b & 1u) wsum += 1.0 / variances_[b];
    detection_variance = 1.0 / wsum;
  }
  image_f_.resize(npix);
  // Per-object metacal detects on the noshear image only, then makes each detection's own metacal
  // stamps from the cell's pixels.
  const int types = options_.per_object_metacal ? 1 : kNumMetacalTypes;
  for (int t = 0; t < types; ++t) {
    const std::size_t at = static_cast<std::size_t>(t) * npix;
    if (one_detection_band) {
      const std::vector<double>& image = images_[detection_band];
      std::transform(image.begin() + at, image.begin() + at + npix, image_f_.begin(),
                     [](double v) { return static_cast<float>(v); });
    } else {
      detection_image_.assign(npix, 0.0);
      for (std::size_t b = 0; b < bands_.size(); ++b) {
        if (!(detect_mask_ >> b & 1u)) continue;
        const double w = detection_variance / variances_[b];
        const double* image = images_[b].data() + at;
        for (std::size_t p = 0; p < npix; ++p) detection_image_[p] += w * image[p];
      }
      std::transform(detection_image_.begin(), detection_image_.end(), image_f_.begin(),
                     [](double v) { return static_cast<float>(v); });
    }
    std::string why;
    if (!detector_.detect(image_f_, cell.size(), cell.size(), std::sqrt(detection_variance), &detections_, &why))
      return fail(std::string(metacal_type_name(kMetacalTypes[t])) + " image: " + why);
    if (options_.per_object_metacal)
      per_object_rows(cell, rows);
    else
      measure_image(cell, t, rows);
  }
  return true;
}

void CellMeasurer::prepare_masked(int side, std::span<const double>* pixels, std::span<const double>* weight,
                                  std::span<const double>* noise) {
  const std::size_t npix = pixels->size();
  double sum = 0;
  long long unmasked = 0;
  for (std::size_t p = 0; p < npix; ++p)
    if (!mask_[p]) sum += weight->empty() ? 1.0 : (*weight)[p], ++unmasked;
  if (unmasked == 0) return;  // nothing to fill from: make() finds no noise and the cell fails
  masked_pixels_.assign(pixels->begin(), pixels->end());
  masked_weight_.assign(weight->begin(), weight->end());  // empty stays empty: no weight map
  masked_noise_.assign(noise->begin(), noise->end());
  if (options_.fill_masked) {
    // The filled pixels carry the unmasked pixels' mean weight: data to deconvolve, not holes.
    const double mean_weight = sum / static_cast<double>(unmasked);
    fill_planes_.clear();
    fill_planes_.emplace_back(masked_pixels_);
    if (!masked_noise_.empty()) fill_planes_.emplace_back(masked_noise_);
    kernels::fill_masked_pixels(mask_, side, fill_planes_, &fill_scratch_);
    for (std::size_t p = 0; p < masked_weight_.size(); ++p)
      if (mask_[p]) masked_weight_[p] = mean_weight;
  } else {
    for (std::size_t p = 0; p < masked_weight_.size(); ++p)
      if (mask_[p]) masked_weight_[p] = 0;  // zeroed by make(), the symmetric mask's pixels too
  }
  *pixels = masked_pixels_, *weight = masked_weight_;
  if (!masked_noise_.empty()) *noise = masked_noise_;
}

void CellMeasurer::measure_image(const MetadetectCell& cell, int type, std::vector<MetadetectRow>* rows) {
  const DetectionStampOptions& so = options_.stamp;
  const int s = cell.size();
  const std::size_t npix = static_cast<std::size_t>(s) * s, nb = bands_.size();
  const std::span<const double> image(images_[0].data() + static_cast<std::size_t>(type) * npix, npix);
  if (band_stamps_.size() < nb) band_stamps_.resize(nb);
  int id = 0;
  for (const Detection& d : detections_) {
    if (!owns(cell, type, d)) continue;
    // Nothing is detected in a star's mask ("nodet"): what is found there is the star's.
    if (std::any_of(cell.stars.begin(), cell.stars.end(), [&](const StarDisc& star) { return star.holds(d.x, d.y); }))
      continue;
    MetadetectRow r;
    r.cell = cell.index;
    r.shear_type = type;
    r.id = id++;
    r.isophotal_area = d.isophotal_area;
    r.sep_flags = d.sep_flags;
    int box = so.size, half = so.size / 2;
    if (so.size == 0) {
      const double radius =
          std::max(so.radius_min, so.radius_factor * std::sqrt(d.isophotal_area / 3.141592653589793)) + so.padding;
      half = std::clamp(static_cast<int>(std::ceil(radius)), (so.box_min - 1) / 2, (so.box_max - 1) / 2);
      box = 2 * half + 1;
    }
    r.box_size = box;
    const int x0 = static_cast<int>(std::lround(d.x)) - half, y0 = static_cast<int>(std::lround(d.y)) - half;
    stamp_.assign(static_cast<std::size_t>(box) * box, 0.0);
    // Row by row: the part inside the cell copied, the rest (beyond its edge) zero.
    const int i0 = std::clamp(-x0, 0, box), i1 = std::clamp(s - x0, i0, box);
    for (int j = 0; j < box; ++j) {
      const int y = y0 + j;
      const int inside = y < 0 || y >= s ? 0 : i1 - i0;
      if (inside < box) r.flags |= kMetadetectEdge;
      if (inside == 0) continue;
      const std::size_t p0 = static_cast<std::size_t>(y) * s + (x0 + i0);
      std::copy_n(image.data() + p0, inside, stamp_.data() + static_cast<std::size_t>(j) * box + i0);
    }
    r.mfrac = masked_share(cell, d.x, d.y);
    const auto [ux, uy] = unsheared(cell, type, d, false);
    set_unsheared_position(cell, ux, uy, &r);
    const double scale2 = cell.pixel_scale * cell.pixel_scale;
    r.psf_orig_e1 = psf_orig_e1_, r.psf_orig_e2 = psf_orig_e2_, r.psf_orig_t = psf_orig_t_ * scale2;
    r.psf_rec_e1 = psf_rec_e1_, r.psf_rec_e2 = psf_rec_e2_;
    const long px = std::lround(d.x), py = std::lround(d.y);
    if (cell_masked_ && px >= 0 && py >= 0 && px < s && py < s && mask_[static_cast<std::size_t>(py) * s + px])
      r.flags |= kMetadetectMasked;
    if (nb == 1) {
      fill_moments(cell, stamp_, box, x0, y0, variances_[0], d, &r);
    } else {
      // The other bands' stamps, cut as the first's (zeros beyond the cell).
      band_stamps_[0].assign(stamp_.begin(), stamp_.end());
      for (std::size_t b = 1; b < nb; ++b) {
        std::vector<double>& st = band_stamps_[b];
        st.assign(static_cast<std::size_t>(box) * box, 0.0);
        const double* img = images_[b].data() + static_cast<std::size_t>(type) * npix;
        for (int j = 0; j < box; ++j)
          for (int i = 0; i < box; ++i) {
            const int x = x0 + i, y = y0 + j;
            if (x >= 0 && y >= 0 && x < s && y < s)
              st[static_cast<std::size_t>(j) * box + i] = img[static_cast<std::size_t>(y) * s + x];
          }
      }
      fill_band_moments(cell, box, x0, y0, d, &r);
    }
    rows->push_back(r);
  }
}

double CellMeasurer::masked_share(const MetadetectCell& cell, double x, double y) {
  const int side = cell.size();
  const double sigma = options_.mfrac_fwhm / psf_scale_ / 2.3548200450309493;
  const int reach = static_cast<int>(std::ceil(3 * sigma));
  const long cx = std::lround(x), cy = std::lround(y);
  // The Gaussian is separable: its weights per column and per row, 2 (2 reach + 1) exponentials.
  share_x_.resize(static_cast<std::size_t>(2 * reach + 1)), share_y_.resize(share_x_.size());
  double sum_x = 0, sum_y = 0;
  for (int k = -reach; k <= reach; ++k) {
    const double dx = static_cast<double>(cx + k) - x, dy = static_cast<double>(cy + k) - y;
    sum_x += share_x_[static_cast<std::size_t>(k + reach)] = std::exp(-0.5 * dx * dx / (sigma * sigma));
    sum_y += share_y_[static_cast<std::size_t>(k + reach)] = std::exp(-0.5 * dy * dy / (sigma * sigma));
  }
  double masked = 0;
  for (int j = -reach; j <= reach; ++j) {
    const long v = cy + j;
    double row = 0;
    for (int i = -reach; i <= reach; ++i) {
      const long u = cx + i;
      const bool outside = u < 0 || v < 0 || u >= side || v >= side;
      const std::size_t p = outside ? 0 : static_cast<std::size_t>(v) * side + static_cast<std::size_t>(u);
      if (outside || (cell_masked_ && mask_[p])) {
        row += share_x_[static_cast<std::size_t>(i + reach)];
      } else if (!cell.mfrac.empty()) {
        row += share_x_[static_cast<std::size_t>(i + reach)] * cell.mfrac[p];
      }
    }
    masked += share_y_[static_cast<std::size_t>(j + reach)] * row;
  }
  return masked / (sum_x * sum_y);
}

std::array<double, 2> CellMeasurer::unsheared(const MetadetectCell& cell, int type, const Detection& d,
                                              bool with_lens) const {
  const std::array<double, 4>& a = filters_[0]->inverse_shear(kMetacalTypes[type]);
  const double c = 0.5 * (cell.size() - 1), dx = d.x - c, dy = d.y - c;
  double ux = a[0] * dx + a[1] * dy, uy = a[2] * dx + a[3] * dy;
  if (with_lens && (cell.lens_g1 != 0 || cell.lens_g2 != 0)) {
    // The scene was sheared by the lens before metacal's step: undone after it.
    const std::array<double, 4> l = inverse_shear_matrix(cell.lens_g1, cell.lens_g2);
    const double lx = l[0] * ux + l[1] * uy, ly = l[2] * ux + l[3] * uy;
    ux = lx, uy = ly;
  }
  return {c + ux, c + uy};
}

void CellMeasurer::set_unsheared_position(const MetadetectCell& cell, double x, double y, MetadetectRow* r) {
  r->x_noshear = cell.origin_x + x, r->y_noshear = cell.origin_y + y;
  if (cell.bmask.empty() && cell.ormask.empty()) return;
  // The pixel nearest the unsheared position, within the cell (as the reference package clips).
  const long s = cell.size();
  const std::size_t p = static_cast<std::size_t>(std::clamp(std::lround(y), 0L, s - 1) * s +
                                                 std::clamp(std::lround(x), 0L, s - 1));
  if (!cell.bmask.empty()) r->bmask = cell.bmask[p];
  if (!cell.ormask.empty()) r->ormask = cell.ormask[p];
}

bool CellMeasurer::owns(const MetadetectCell& cell, int type, const Detection& d) const {
  // Whether the cell keeps a detection is decided where it lies in the unsheared cell: a sheared
  // image shows the scene's point c + A^-1 (x - c) at pixel x, each cell sheared about its own
  // centre c. Tested in the sheared image, an object near the edge of the inner region would leave
  // or enter it with the metacal shear: a term in R from cell boundaries alone, which the next
  // cell's image (sheared about another centre) does not cancel.
  const auto [x, y] = unsheared(cell, type, d, true);
  return x >= cell.keep_x0 && x < cell.keep_x1 && y >= cell.keep_y0 && y < cell.keep_y1;
}

namespace {

// A detection's moments m of the stamp whose pixel (0, 0) is the cell's (x0, y0) into its row;
// psf_t: the reconvolution PSF's T under the weight, pixels^2.
void store_moments(const MetadetectCell& cell, const kernels::WeightedMoments& m, double psf_t, int x0, int y0,
                   const Detection& d, MetadetectRow* r) {
  const double scale2 = cell.pixel_scale * cell.pixel_scale;
  r->psf_t = psf_t * scale2;
  if (!m.valid) {
    r->flags |= kMetadetectMomentsFailed;
    r->x = cell.origin_x + d.x, r->y = cell.origin_y + d.y;
  } else {
    r->x = cell.origin_x + x0 + m.x, r->y = cell.origin_y + y0 + m.y;
    r->e1 = m.e1, r->e2 = m.e2, r->e1_err = m.e1_err, r->e2_err = m.e2_err;
    r->t = m.t * scale2;
    r->t_ratio = m.t / psf_t;
    r->flux = m.flux, r->snr = m.snr;
  }
  r->u = r->x * cell.pixel_scale, r->v = r->y * cell.pixel_scale;
}

// pgauss: the pre-PSF moments p into the row, its position the wmom centroid c (the detection's
// where that failed).
void store_prepsf(const MetadetectCell& cell, const kernels::WeightedMoments& c, const kernels::PrepsfMoments& p,
                  double psf_t, int x0, int y0, const Detection& d, MetadetectRow* r) {
  const double scale2 = cell.pixel_scale * cell.pixel_scale;
  r->psf_t = psf_t * scale2;
  if (c.valid)
    r->x = cell.origin_x + x0 + c.x, r->y = cell.origin_y + y0 + c.y;
  else
    r->x = cell.origin_x + d.x, r->y = cell.origin_y + d.y;
  if (!p.valid) {
    r->flags |= kMetadetectMomentsFailed;
  } else {
    r->e1 = p.e1, r->e2 = p.e2, r->e1_err = p.e1_err, r->e2_err = p.e2_err;
    r->t = p.t * scale2;
    r->t_ratio = p.t / psf_t;
    r->flux = p.flux, r->snr = p.snr;
  }
  r->u = r->x * cell.pixel_scale, r->v = r->y * cell.pixel_scale;
}

}  // namespace

std::span<const double> CellMeasurer::psf_transform(int box, std::size_t band) {
  const std::size_t slot = static_cast<std::size_t>(box) / 2, role = shear_mask_ >> band & 1u ? 0 : 1;
  if (psf_k_[role].size() <= slot) psf_k_[role].resize(slot + 1);
  std::vector<double>& k = psf_k_[role][slot];
  if (k.empty()) {
    // What a point source is in the metacal images: Gamma x the pixel's top-hat (sinc(k / 2) per
    // axis), so that the moments are of the galaxy before both. Gamma is round (a Gaussian or a Moffat): real.
    // A cell tile's every cell has its own Gamma, and a Moffat's transform costs a Bessel function:
    // Gamma and the pixel are even in kx and ky, so one quadrant is evaluated and mirrored, and
    // only where the weight's transform is not negligible (the kernel reads no other k; 1 there).
    const PsfModel& gamma = filters_[band]->reconvolution();
    auto pixel = [](double k) { return k == 0 ? 1.0 : std::sin(0.5 * k) / (0.5 * k); };
    const double s = weight_fwhm_px_ / 2.3548200450309493;
    const int h = box / 2 + 1;
    k.resize(static_cast<std::size_t>(box) * box);
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < h; ++i) {
        const double kx = kernels::dft_frequency(i, box), ky = kernels::dft_frequency(j, box);
        const bool needed = 0.5 * s * s * (kx * kx + ky * ky) < 40;  // the kernel's cut: e^-34.5
        k[static_cast<std::size_t>(j) * box + i] =
            needed ? std::real(gamma.k_value(kx, ky)) * pixel(kx) * pixel(ky) : 1.0;
      }
    for (int j = 0; j < box; ++j)
      for (int i = 0; i < box; ++i)
        if (i >= h || j >= h)
          k[static_cast<std::size_t>(j) * box + i] =
              k[static_cast<std::size_t>(j < h ? j : box - j) * box + (i < h ? i : box - i)];
  }
  return k;
}

kernels::PrepsfMoments CellMeasurer::prepsf(std::span<const double> stamp, int box,
                                            const kernels::WeightedMoments& centre, int x0, int y0, double variance,
                                            const Detection& d, std::size_t band) {
  const double xc = centre.valid ? centre.x : d.x - x0, yc = centre.valid ? centre.y : d.y - y0;
  return kernels::prepsf_moments(stamp, box, xc, yc, weight_fwhm_px_, psf_transform(box, band), variance,
                                 prepsf_scratch_);
}

void CellMeasurer::fill_moments(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0,
                                double variance, const Detection& d, MetadetectRow* r) {
  if (fitter_) return fill_fit(cell, stamp, box, x0, y0, variance, d, r);
  scratch_.resize(2 * static_cast<std::size_t>(box));
  const kernels::WeightedMoments m = kernels::weighted_moments(stamp, box, weight_fwhm_px_, variance, scratch_,
                                                               centroid_iterations(), d.x - x0, d.y - y0);
  if (options_.measurement == MetadetectMeasurement::kPgauss)
    store_prepsf(cell, m, prepsf(stamp, box, m, x0, y0, variance, d, 0), psf_t_, x0, y0, d, r);
  else
    store_moments(cell, m, psf_t_, x0, y0, d, r);
  r->band_flux[0] = r->flux, r->band_snr[0] = r->snr;
}

void CellMeasurer::fill_fit(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0,
                            double variance, const Detection& d, MetadetectRow* r) {
  const double scale2 = cell.pixel_scale * cell.pixel_scale;
  r->psf_t = psf_t_ * scale2;
  r->x = cell.origin_x + d.x, r->y = cell.origin_y + d.y;
  r->u = r->x * cell.pixel_scale, r->v = r->y * cell.pixel_scale;
  const std::size_t slot = static_cast<std::size_t>(box) / 2;
  if (fit_psfs_.size() <= slot) fit_psfs_.resize(slot + 1);
  std::string why;
  if (!fit_psfs_[slot]) fit_psfs_[slot] = fitter_->renderer_for(box).prepare_psf(filters_[shape_band_]->reconvolution(), &why);
  if (!fit_psfs_[slot]) {
    r->flags |= kMetadetectMomentsFailed;
    return;
  }
  // The metacal images' noise is correlated; the fit weighs it as white of its variance, as its
  // errors and S/N then are. A model of one galaxy cannot fit its neighbours' light as moments
  // weigh it away: the pixels nearer another detection of the image than this one are masked (the
  // "uberseg" of MEDS fits; every image's own detections, so the sheared images mask alike), as
  // are those beyond the cell. Without, the 7 x 7 grid's exp fits gave R11 0.63, R22 0.26.
  fit_neighbours_.clear();
  for (const Detection& n : detections_)
    if (&n != &d && std::abs(n.x - d.x) < box && std::abs(n.y - d.y) < box) fit_neighbours_.push_back({n.x, n.y});
  fit_weight_.resize(static_cast<std::size_t>(box) * box);
  const int s = cell.size();
  for (int j = 0; j < box; ++j)
    for (int i = 0; i < box; ++i) {
      const double x = x0 + i, y = y0 + j;
      bool keep = x >= 0 && y >= 0 && x < s && y < s;
      const double own = (x - d.x) * (x - d.x) + (y - d.y) * (y - d.y);
      for (std::size_t k = 0; keep && k < fit_neighbours_.size(); ++k) {
        const double dx = x - fit_neighbours_[k][0], dy = y - fit_neighbours_[k][1];
        keep = dx * dx + dy * dy >= own;
      }
      fit_weight_[static_cast<std::size_t>(j) * box + i] = keep ? 1 / variance : 0.0;
    }
  Observation o;
  o.pixels = stamp;
  o.weight = fit_weight_;
  o.box_size = box;
  o.psf = fit_psfs_[slot];
  const FitResult f = fitter_->fit({&o, 1});
  const double e1 = f.params[index(Param::kE1)], e2 = f.params[index(Param::kE2)];
  const double e2sum = e1 * e1 + e2 * e2;
  if (f.status != FitStatus::kOk || !(e2sum < 1)) {
    r->flags |= kMetadetectMomentsFailed;
    return;
  }
  r->x = cell.origin_x + x0 + f.params[index(Param::kX0)], r->y = cell.origin_y + y0 + f.params[index(Param::kY0)];
  r->u = r->x * cell.pixel_scale, r->v = r->y * cell.pixel_scale;
  r->e1 = e1, r->e2 = e2, r->e1_err = f.e1_err, r->e2_err = f.e2_err;
  // The model's T = Mxx + Myy: a Sersic of circularised half-light radius h and e = (a - b) / (a + b)
  // has T = <r^2>_round (1 + |e|^2) / (1 - |e|^2), <r^2>_round = sersic_mean_r2(n) h^2; bd's
  // components averaged by flux (the bulge of the disc's e: its delta_e held at 0 by default).
  const double h = f.params[index(Param::kRadius)], stretch = (1 + e2sum) / (1 - e2sum);
  const double disc = std::isfinite(f.disc_flux) ? f.disc_flux : 0;
  const double bulge = std::isfinite(f.bulge_flux) ? f.bulge_flux : 0;
  double m2 = kernels::sersic_mean_r2(f.params[index(Param::kDiscIndex)]) * h * h;
  if (bulge != 0 && disc + bulge != 0) {
    const double hb = h * f.params[index(Param::kRadiusRatio)];
    m2 = (disc * m2 + bulge * kernels::sersic_mean_r2(f.params[index(Param::kBulgeIndex)]) * hb * hb) / (disc + bulge);
  }
  const double t = m2 * stretch;
  r->t = t * scale2;
  r->t_ratio = t / psf_t_;
  r->flux = f.flux, r->snr = f.snr;
  r->band_flux[0] = r->flux, r->band_snr[0] = r->snr;
}

void CellMeasurer::fill_band_moments(const MetadetectCell& cell, int box, int x0, int y0, const Detection& d,
                                     MetadetectRow* r) {
  // As `stampede fit`'s multi-band wmom: one weight, the shape bands' sums averaged with weights
  // of their inverse noise variance; each band's flux and S/N under the same weight about its own
  // centroid.
  stamps_.clear();
  for (std::size_t b = 0; b < bands_.size(); ++b) {
    if (!(shear_mask_ >> b & 1u)) continue;
    kernels::MomentsStamp st;
    st.image = band_stamps_[b];
    st.size = box;
    st.variance = variances_[b];
    st.start_x = d.x - x0, st.start_y = d.y - y0;
    stamps_.push_back(st);
  }
  const kernels::WeightedMoments m = kernels::weighted_moments(stamps_, weight_fwhm_px_, scratch_, centroid_iterations());
  if (options_.measurement == MetadetectMeasurement::kPgauss) {
    // The moments are linear in the pixels and every band has the one Gamma, so the bands' sums
    // averaged with weights 1 / variance_b are the moments of the bands' stamps so averaged, whose
    // noise variance is 1 / sum_b (1 / variance_b). Each band's flux and S/N about the same centre.
    const std::size_t npix = static_cast<std::size_t>(box) * box;
    combined_.assign(npix, 0.0);
    double wsum = 0;
    for (std::size_t b = 0; b < bands_.size(); ++b)
      if (shear_mask_ >> b & 1u) wsum += 1 / variances_[b];
    for (std::size_t b = 0; b < bands_.size(); ++b) {
      if (!(shear_mask_ >> b & 1u)) continue;
      const double w = 1 / variances_[b] / wsum;
      for (std::size_t p = 0; p < npix; ++p) combined_[p] += w * band_stamps_[b][p];
    }
    store_prepsf(cell, m, prepsf(combined_, box, m, x0, y0, 1 / wsum, d, shape_band_), psf_t_, x0, y0, d, r);
    for (std::size_t b = 0; b < bands_.size(); ++b) {
      const kernels::PrepsfMoments mb = prepsf(band_stamps_[b], box, m, x0, y0, variances_[b], d, b);
      if (mb.valid) r->band_flux[b] = mb.flux, r->band_snr[b] = mb.snr;
    }
    return;
  }
  store_moments(cell, m, psf_t_, x0, y0, d, r);
  scratch_.resize(std::max(scratch_.size(), 2 * static_cast<std::size_t>(box)));
  for (std::size_t b = 0; b < bands_.size(); ++b) {
    const kernels::WeightedMoments mb = kernels::weighted_moments(band_stamps_[b], box, weight_fwhm_px_, variances_[b],
                                                                  scratch_, centroid_iterations(), d.x - x0, d.y - y0);
    if (mb.valid) r->band_flux[b] = mb.flux, r->band_snr[b] = mb.snr;
  }
}

void CellMeasurer::per_object_rows(const MetadetectCell& cell, std::vector<MetadetectRow>* rows) {
  const int box = kPerObjectStamp, half = box / 2, s = cell.size();
  const MetadetectBand& band = cell.bands.front();
  const std::size_t npix = static_cast<std::size_t>(box) * box;
  stamp_images_.resize(kNumMetacalTypes * npix);
  stamp_pixels_.resize(npix);
  stamp_weight_.resize(npix);
  stamp_noise_.resize(band.noise.empty() ? 0 : npix);
  MetacalOptions metacal;
  metacal.enabled = true;
  metacal.step = options_.step;
  metacal.fixnoise = options_.fixnoise;
  int id = 0;
  for (const Detection& d : detections_) {
    if (!owns(cell, 0, d)) continue;
    const int x0 = static_cast<int>(std::lround(d.x)) - half, y0 = static_cast<int>(std::lround(d.y)) - half;
    std::uint32_t flags = 0;
    long long masked = 0;
    for (int j = 0; j < box; ++j)
      for (int i = 0; i < box; ++i) {
        const int x = x0 + i, y = y0 + j;
        const std::size_t q = static_cast<std::size_t>(j) * box + i;
        if (x < 0 || y < 0 || x >= s || y >= s) {
          stamp_pixels_[q] = 0, stamp_weight_[q] = 0, flags |= kMetadetectEdge, ++masked;
          if (!stamp_noise_.empty()) stamp_noise_[q] = 0;
          continue;
        }
        const std::size_t p = static_cast<std::size_t>(y) * s + x;
        stamp_pixels_[q] = band.image.pixels[p];
        if (!stamp_noise_.empty()) stamp_noise_[q] = band.noise[p];
        stamp_weight_[q] = band.image.weight.empty() ? 1.0 : band.image.weight[p];
        if (!(stamp_weight_[q] > 0)) ++masked;
      }
    if (masked > 0 && !(flags & kMetadetectEdge)) flags |= kMetadetectMasked;
    double variance = 0;
    stamp_set_->make(stamp_pixels_, stamp_weight_, WeightKind::kInverseVariance, 0.0, *stamp_filters_, metacal,
                     RandomStream({options_.seed, static_cast<std::uint64_t>(cell.index), kFixnoisePurpose,
                                   static_cast<std::uint64_t>(id)}),
                     stamp_images_, &variance, 1.0, nullptr, stamp_noise_);
    for (int t = 0; t < kNumMetacalTypes; ++t) {
      MetadetectRow r;
      r.cell = cell.index;
      r.shear_type = t;
      r.id = id;
      r.isophotal_area = d.isophotal_area;
      r.sep_flags = d.sep_flags;
      r.box_size = box;
      r.flags = flags;
      r.mfrac = static_cast<double>(masked) / static_cast<double>(npix);
      set_unsheared_position(cell, d.x, d.y, &r);
      fill_moments(cell, std::span<const double>(stamp_images_).subspan(t * npix, npix), box, x0, y0, variance, d, &r);
      rows->push_back(r);
    }
    ++id;
  }
}

}  // namespace stampede
