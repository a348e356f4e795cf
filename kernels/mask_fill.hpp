// Masked pixels of a square cell made harmless to metacal's shear (issue 56; the reference
// package's rules, docs/survey_metadetect.md): the mask made symmetric under quarter turns about
// the cell's centre, so its shape has no quadrupole to shear the image by, and the masked pixels
// filled from the unmasked ones around them, so that deconvolution and shear see no hole.
#pragma once
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace stampede::kernels {

// mask |= mask turned by 90, 180 and 270 degrees about the centre of the side x side cell
// ((side - 1) / 2 on each axis; four-fold, as the reference package's): a pixel is masked when it
// or a pixel a quarter turn, a half turn or three quarters away is. `turned` is scratch.
void symmetrise_mask(std::span<std::uint8_t> mask, int side, std::vector<std::uint8_t>* turned);

// Scratch kept between calls (steady state allocates nothing).
struct MaskFillScratch {
  std::vector<double> values, rows[3], kernel[3];
  std::vector<double> share[6], fit[3];  // the unmasked pixels' Gaussian moments; a plane's
  std::vector<std::size_t> pending, now, later;  // pixels still to fill; those a scale fills
};

// Each masked pixel (mask != 0) of the side x side `planes` (each filled the same way: an image
// and its noise field) replaced by the value at it of a plane a + b dx + c dy fitted by least
// squares to the unmasked pixels about it under a Gaussian weight (a ramp is filled exactly, a
// smooth profile to second order), the Gaussian's sigma the least of 1, 2, 4, ... 64 pixels at
// which the unmasked pixels hold at least a quarter of its weight there (a thin column takes its
// neighbours, a star's disc a wider ring); where the unmasked pixels there lie on a line, their
// weighted mean. A pixel no scale reaches (a cell masked almost whole) takes the unmasked pixels'
// mean. Unmasked pixels are unchanged. Returns the number of pixels filled.
long long fill_masked_pixels(std::span<const std::uint8_t> mask, int side, std::span<const std::span<double>> planes,
                             MaskFillScratch* scratch);

}  // namespace stampede::kernels
