// An analytic PSF convolved with the pixel, sampled on an n x n grid about its middle pixel: what
// a point source is in an image of that PSF (metacal's reconvolution PSF's weighted T, the Gaussian
// fitted to an analytic PSF).
#pragma once

#include <span>

#include "engine/model/psf_model.hpp"

namespace stampede {

// out[y * n + x] = the mean of sub x sub point values (PsfModel::x_value) over pixel (x, y), pixel
// centres at integers, the profile's centre at (n - 1) / 2. out: n x n.
void pixelated_psf(const PsfModel& psf, int n, int sub, std::span<double> out);

}  // namespace stampede
