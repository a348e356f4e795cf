// Block averaging from the upsampled model grid to data resolution.
#pragma once

namespace stampede::kernels {

// out[y * out_size + x] = mean of the factor x factor block of `in` (row-major, in_size per row)
// whose first sub-pixel is (offset + x * factor, offset + y * factor).
void block_average(const double* in, int in_size, int factor, int offset, int out_size, double* out);

}  // namespace stampede::kernels
