// Metadetection of one cell; see cell_measurer.hpp.
#include "engine/metadetect/cell_measurer.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "engine/common/random_stream.hpp"
#include "engine/metacal/metacal_options.hpp"
#include "engine/metacal/metacal_type.hpp"
#include "engine/metacal/reconvolution_psf.hpp"
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

// The reconvolution PSF convolved with the pixel (what a point source is in the metacal images),
// sampled n x n about the middle pixel: each pixel the mean of sub x sub point values.
std::vector<double> pixelated_psf_image(const PsfModel& psf, int n, int sub) {
  std::vector<double> out(static_cast<std::size_t>(n) * n);
  const double c = 0.5 * (n - 1);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      double sum = 0;
      for (int j = 0; j < sub; ++j)
        for (int i = 0; i < sub; ++i)
          sum += psf.x_value(x - c - 0.5 + (i + 0.5) / sub, y - c - 0.5 + (j + 0.5) / sub);
      out[static_cast<std::size_t>(y) * n + x] = sum / (sub * sub);
    }
  return out;
}

}  // namespace

CellMeasurer::CellMeasurer(const MetadetectOptions& options, FftPlanning planning)
    : options_(options), planning_(planning), filter_(detection_filter(options.detection)) {}

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

}  // namespace

bool CellMeasurer::prepare_psf(const PsfModel& psf, double pixel_scale, std::string* problem) {
  if (have_psf_ && same_psf(psf, psf_) && pixel_scale == psf_scale_) return filters_ != nullptr;
  have_psf_ = true;
  psf_ = psf;
  psf_scale_ = pixel_scale;
  MetacalOptions metacal;
  metacal.enabled = true;
  metacal.step = options_.step;
  metacal.psf_dilation = options_.psf_dilation;
  std::string why;
  filters_ = reconvolution_filters(psf, metacal, images_set_->period(), &why);
  if (!filters_) {
    *problem = "no metacal reconvolution PSF serves this PSF: " + why;
    return false;
  }
  weight_fwhm_px_ = options_.weight_fwhm / pixel_scale;
  // The point source's T under the same weight, as the detections' T is measured.
  const int n = 2 * static_cast<int>(std::ceil(4 * weight_fwhm_px_)) + 1;
  const std::vector<double> image = pixelated_psf_image(filters_->reconvolution(), n, 5);
  std::vector<double> scratch(2 * static_cast<std::size_t>(n));
  const kernels::WeightedMoments m = kernels::weighted_moments(image, n, weight_fwhm_px_, 0.0, scratch);
  if (!m.valid) {
    filters_.reset();
    *problem = "the reconvolution PSF's weighted moments are not valid";
    return false;
  }
  psf_t_ = m.t;
  if (options_.per_object_metacal) {
    if (!stamp_set_) stamp_set_ = std::make_unique<MetacalImageSet>(kPerObjectStamp, planning_);
    stamp_filters_ = reconvolution_filters(psf, metacal, stamp_set_->period(), &why);
    if (!stamp_filters_) {
      filters_.reset();
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
  if (!images_set_ || images_set_->stamp_size() != cell.size)
    images_set_ = std::make_unique<MetacalImageSet>(cell.size, planning_,
                                                    MetacalImager::padded_size(cell.size, kCellMargin)),
    have_psf_ = false;
  if (!cell.psf) return fail("no PSF");
  if (!prepare_psf(*cell.psf, cell.pixel_scale, problem)) return fail(*problem);
  const std::size_t npix = static_cast<std::size_t>(cell.size) * cell.size;
  images_.resize(kNumMetacalTypes * npix);
  MetacalOptions metacal;
  metacal.enabled = true;
  metacal.step = options_.step;
  metacal.fixnoise = options_.fixnoise;
  double variance = 0;
  images_set_->make(cell.pixels, cell.weight, WeightKind::kInverseVariance, 0.0, *filters_, metacal,
                    RandomStream({options_.seed, static_cast<std::uint64_t>(cell.index), kFixnoisePurpose}), images_,
                    &variance);
  if (!(variance > 0) || !std::isfinite(variance)) return fail("the cell's weights give no positive finite noise variance");
  image_f_.resize(npix);
  // Per-object metacal detects on the noshear image only, then makes each detection's own metacal
  // stamps from the cell's pixels.
  const int types = options_.per_object_metacal ? 1 : kNumMetacalTypes;
  for (int t = 0; t < types; ++t) {
    const std::span<const double> image(images_.data() + t * npix, npix);
    std::transform(image.begin(), image.end(), image_f_.begin(), [](double v) { return static_cast<float>(v); });
    std::string why;
    if (!detect_objects(image_f_, cell.size, cell.size, std::sqrt(variance), options_.detection, filter_, &detection_scratch_,
                        &detections_, &why))
      return fail(std::string(metacal_type_name(kMetacalTypes[t])) + " image: " + why);
    if (options_.per_object_metacal)
      per_object_rows(cell, rows);
    else
      measure_image(cell, t, image, variance, rows);
  }
  return true;
}

void CellMeasurer::measure_image(const MetadetectCell& cell, int type, std::span<const double> image, double variance,
                                 std::vector<MetadetectRow>* rows) {
  const DetectionStampOptions& so = options_.stamp;
  const int s = cell.size;
  int id = 0;
  for (const Detection& d : detections_) {
    if (!owns(cell, type, d)) continue;
    MetadetectRow r;
    r.cell = cell.index;
    r.shear_type = type;
    r.id = id++;
    r.isophotal_area = d.isophotal_area;
    r.sep_flags = d.sep_flags;
    const double radius =
        std::max(so.radius_min, so.radius_factor * std::sqrt(d.isophotal_area / 3.141592653589793)) + so.padding;
    const int half = std::clamp(static_cast<int>(std::ceil(radius)), (so.box_min - 1) / 2, (so.box_max - 1) / 2);
    const int box = 2 * half + 1;
    r.box_size = box;
    const int x0 = static_cast<int>(std::lround(d.x)) - half, y0 = static_cast<int>(std::lround(d.y)) - half;
    stamp_.assign(static_cast<std::size_t>(box) * box, 0.0);
    long long masked = 0;
    for (int j = 0; j < box; ++j) {
      const int y = y0 + j;
      for (int i = 0; i < box; ++i) {
        const int x = x0 + i;
        if (x < 0 || y < 0 || x >= s || y >= s) {
          r.flags |= kMetadetectEdge;
          ++masked;
          continue;
        }
        const std::size_t p = static_cast<std::size_t>(y) * s + x;
        if (!cell.weight.empty() && !(cell.weight[p] > 0)) ++masked;
        stamp_[static_cast<std::size_t>(j) * box + i] = image[p];
      }
    }
    r.mfrac = static_cast<double>(masked) / (static_cast<double>(box) * box);
    if (masked > 0 && !(r.flags & kMetadetectEdge)) r.flags |= kMetadetectMasked;
    fill_moments(cell, stamp_, box, x0, y0, variance, d, &r);
    rows->push_back(r);
  }
}

bool CellMeasurer::owns(const MetadetectCell& cell, int type, const Detection& d) const {
  // Whether the cell keeps a detection is decided where it lies in the unsheared cell: a sheared
  // image shows the scene's point c + A^-1 (x - c) at pixel x, each cell sheared about its own
  // centre c. Tested in the sheared image, an object near the edge of the inner region would leave
  // or enter it with the metacal shear: a term in R from cell boundaries alone, which the next
  // cell's image (sheared about another centre) does not cancel.
  const std::array<double, 4>& a = filters_->inverse_shear(kMetacalTypes[type]);
  const double c = 0.5 * (cell.size - 1), dx = d.x - c, dy = d.y - c;
  const double x = c + a[0] * dx + a[1] * dy, y = c + a[2] * dx + a[3] * dy;
  return x >= cell.keep_x0 && x < cell.keep_x1 && y >= cell.keep_y0 && y < cell.keep_y1;
}

void CellMeasurer::fill_moments(const MetadetectCell& cell, std::span<const double> stamp, int box, int x0, int y0,
                                double variance, const Detection& d, MetadetectRow* r) {
  scratch_.resize(2 * static_cast<std::size_t>(box));
  const kernels::WeightedMoments m = kernels::weighted_moments(stamp, box, weight_fwhm_px_, variance, scratch_);
  const double scale2 = cell.pixel_scale * cell.pixel_scale;
  r->psf_t = psf_t_ * scale2;
  if (!m.valid) {
    r->flags |= kMetadetectMomentsFailed;
    r->x = cell.origin_x + d.x, r->y = cell.origin_y + d.y;
  } else {
    r->x = cell.origin_x + x0 + m.x, r->y = cell.origin_y + y0 + m.y;
    r->e1 = m.e1, r->e2 = m.e2, r->e1_err = m.e1_err, r->e2_err = m.e2_err;
    r->t = m.t * scale2;
    r->t_ratio = m.t / psf_t_;
    r->flux = m.flux, r->snr = m.snr;
  }
  r->u = r->x * cell.pixel_scale, r->v = r->y * cell.pixel_scale;
}

void CellMeasurer::per_object_rows(const MetadetectCell& cell, std::vector<MetadetectRow>* rows) {
  const int box = kPerObjectStamp, half = box / 2, s = cell.size;
  const std::size_t npix = static_cast<std::size_t>(box) * box;
  stamp_images_.resize(kNumMetacalTypes * npix);
  stamp_pixels_.resize(npix);
  stamp_weight_.resize(npix);
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
          continue;
        }
        const std::size_t p = static_cast<std::size_t>(y) * s + x;
        stamp_pixels_[q] = cell.pixels[p];
        stamp_weight_[q] = cell.weight.empty() ? 1.0 : cell.weight[p];
        if (!(stamp_weight_[q] > 0)) ++masked;
      }
    if (masked > 0 && !(flags & kMetadetectEdge)) flags |= kMetadetectMasked;
    double variance = 0;
    stamp_set_->make(stamp_pixels_, stamp_weight_, WeightKind::kInverseVariance, 0.0, *stamp_filters_, metacal,
                     RandomStream({options_.seed, static_cast<std::uint64_t>(cell.index), kFixnoisePurpose,
                                   static_cast<std::uint64_t>(id)}),
                     stamp_images_, &variance);
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
      fill_moments(cell, std::span<const double>(stamp_images_).subspan(t * npix, npix), box, x0, y0, variance, d, &r);
      rows->push_back(r);
    }
    ++id;
  }
}

}  // namespace stampede
