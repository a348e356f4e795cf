// How a header value given as text is written to a FITS card: as a string, an integer or a real.
#pragma once

namespace stampede::io {

enum class HeaderValueType {
  kText,     // 'value' (a string card)
  kInteger,  // an integer card where the text is an integer
  kReal,     // a real card (with a decimal point or exponent) where the text is a finite number
};

}  // namespace stampede::io
