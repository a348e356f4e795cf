// A bright star's mask as a metadetection cell carries it: a disc, in the cell's 0-based pixels,
// whose pixels are masked (then filled, as every masked pixel) and inside which no detection is
// kept ("nodet", as the reference package drops detections in its star masks).
#pragma once

namespace stampede {

struct StarDisc {
  double x = 0, y = 0;  // centre, 0-based pixels of the cell (or, in a catalogue, of the image)
  double radius = 0;    // pixels, the margin included
  bool holds(double px, double py) const { return (px - x) * (px - x) + (py - y) * (py - y) < radius * radius; }
};

}  // namespace stampede
