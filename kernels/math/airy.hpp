// The FWHM of the unobscured Airy disc in units of lambda / D.
#pragma once

namespace stampede::kernels {

// [2 J1(pi x) / (pi x)]^2 = 1/2 at x = 0.5144969849810940 (x in lambda / D), so the FWHM is twice
// that. Obscured pupils (obscuration > 0) have a narrower core and do not use this.
inline constexpr double kAiryFwhmOverLambdaOverD = 1.028993969962188;

}  // namespace stampede::kernels
