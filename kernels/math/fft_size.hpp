// FFT-friendly transform sizes.
#pragma once

namespace stampede::kernels {

// Smallest n' >= max(n, 1) whose only prime factors are 2, 3, 5 and 7 (FFTW's fast sizes).
int fft_friendly_size(int n);

}  // namespace stampede::kernels
