// The unnormalised sinc function, sin(x) / x: the Fourier transform of a top-hat pixel.
#pragma once

namespace stampede::kernels {

// sin(x) / x, and 1 at x = 0. Below |x| = 1e-8 the series' next term x^2 / 6 is under 2^-54, half
// an ulp of 1, so sin(x) / x rounds to exactly 1 there: the branch returns that value without the
// 0 / 0 at x = 0 (a 1 - x^2 / 6 branch would round to the same 1).
double sinc(double x);

}  // namespace stampede::kernels
