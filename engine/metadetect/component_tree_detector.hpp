// Source Extractor's detection (as SEP 1.2 implements it; ../shared/reference/sep-detection.md)
// built for deep, crowded images: a pixel above the threshold on the filtered image joins its
// 8-connected segment; a segment of at least min_area pixels is deblended over N levels spaced
// exponentially between the threshold and its peak, by the contrast criterion, its remaining pixels
// gathered into the children; spurious detections near bright objects are cleaned away.
//
// SEP re-segments every node's bounding box at every level (Lutz's scan, a copy per component,
// a linear search for its parent) and draws each unclaimed pixel's child at random with an expf per
// child. Here one pass over the segment's pixels, taken level by level from the peak down, joins
// them with a union-find: the components at every level at once (a component tree), each pixel
// remembering the deepest node it reached. Each unclaimed pixel goes to its most probable child (the
// largest of SEP's weights), so that a blend's pixels do not change at random between images.
// Buffers are kept between calls: steady state allocates nothing.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "engine/metadetect/detection.hpp"
#include "engine/metadetect/metadetect_options.hpp"

namespace stampede {

class ComponentTreeDetector {
 public:
  // Detects on `filtered` (the detection image, filtered as options say; width x height, x
  // fastest) with the absolute threshold `threshold` (options.threshold x the noise sigma); flux and
  // isophotal area are of `raw`, the unfiltered image (the same as `filtered` without a filter).
  // `out` is replaced, in the order SEP completes its objects (by the last row of each segment).
  void detect(std::span<const float> filtered, std::span<const float> raw, int width, int height, float threshold,
              const DetectionOptions& options, std::vector<Detection>* out);

 private:
  // A component at one deblending level.
  struct Node {
    int level = 0;
    int npix = 0;
    float flux = 0;          // sum of the filtered values of its pixels
    int rep = 0;             // one of its pixels (the union-find root when it was recorded)
    int parent = -1;
    int key = 0;             // its last pixel in raster order: Lutz's completion order
    int order = 0;           // rank within its level (parent's rank, then completion)
    int first_son = -1, next_sibling = -1;
    int tin = 0, tout = 0;   // depth-first numbering: its subtree's nodes are [tin, tout)
    int cursor = -1;         // the numbering's next son
    bool ok = true;          // no split below
  };
  // SEP's objstruct, as far as the catalogue and the cleaning read it.
  struct Object {
    float thresh = 0;        // SEP's dthresh: a core's level, else the detection threshold
    int npix = 0;
    double cflux_sum = 0;    // sum of the filtered values v; cflux the float SEP divides by
    float cflux = 0, peak = 0;
    int xmin = 0, xmax = 0, ymin = 0, ymax = 0;
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;  // sums of v x, v y, v x^2, ... (image's origin)
    int area2 = 0;
    double half_peak = 0;    // (threshold + peak) / 2: SEP's thresh2
    double mx = 0, my = 0;
    float a = 0, b = 0, cxx = 0, cyy = 0, cxy = 0, abcor = 1;
    float mthresh = 0;
    double raw_flux = 0;     // the unfiltered pixels' sum, and how many are above the threshold
    int raw_above = 0;
    bool edge = false;       // a pixel on the image's edge
    bool core_edge = false;  // a merged child's core's
    bool singular = false;
    bool merged = false;
    int heap_count = 0;      // SEP's countdown in its mthresh selection
  };

  void segment(std::span<const float> filtered, float threshold);
  int find(int p);
  int row(int p) const;
  // One segment's objects appended to objects_, each owning its pixels in owner_.
  void deblend_segment(std::span<const int> pixels, std::span<const float> filtered, std::span<const float> raw,
                       float threshold, const DetectionOptions& options);
  // The segment's component tree over the deblending levels, cut by the contrast criterion: the
  // output children's nodes in outputs_ (none: the segment is one object).
  void build_tree(std::span<const int> pixels, std::span<const float> filtered, float threshold, float peak,
                  float root_flux, const DetectionOptions& options);
  void add_pixel(int p, float v);
  void snapshot(int level, int min_node_pixels);
  // The segment's pixels that no child's core holds, each to its child (owner_).
  void gather_up(std::span<const int> pixels, int first_object, int n_children, float threshold);
  // Objects [first, objects_.size()) measured over the pixels each owns (owner_); final: a merged
  // object centred on its core, and the cleaning's mthresh.
  void analyse(std::span<const int> pixels, std::span<const float> filtered, std::span<const float> raw, int first,
               bool final);
  // The cleaning's mthresh of objects [first, objects_.size()).
  void mthresh(std::span<const int> pixels, std::span<const float> filtered, int first, int min_area);
  void clean(double beta);

  int width_ = 0, height_ = 0;
  std::vector<int> seg_parent_;         // per pixel: segmentation union-find, -1 below the threshold
  std::vector<int> seg_count_, seg_start_, seg_pixels_, seg_roots_;
  std::vector<int> above_;  // segment()'s pixels above the threshold, in raster order
  // Per pixel: the level union-find's parent (-1: not yet added); a root's Component record is
  // its component's (apart, so that the finds touch 4 bytes a pixel).
  std::vector<int> parent_;
  struct Component {
    int size = 0;
    int key = 0;      // the last pixel in raster order
    int stamp = -1;   // the level at which `node` was recorded
    int node = 0;
    double flux = 0;  // sum of the filtered values
  };
  std::vector<Component> components_;
  std::uint64_t row_multiplier_ = 0;  // ceil(2^32 / width) where p / width is (p x it) >> 32
  std::vector<int> assigned_;           // per pixel: the deepest node holding it
  std::vector<int> owner_;              // per pixel: its object, -1 none yet
  std::vector<std::uint8_t> in_core_;   // per pixel: in a deblended child's core
  std::vector<int> live_, pending_, band_count_, band_order_;
  std::vector<float> levels_;
  std::vector<std::uint8_t> pixel_band_;
  std::vector<Node> nodes_;
  std::vector<int> level_first_;        // nodes_ index of each level's first node
  std::vector<int> node_remap_, sort_index_;
  std::vector<Node> sorted_nodes_;
  std::vector<int> core_pixels_, outputs_, dfs_stack_, bucket_start_, bucket_cursor_, bucket_pixels_;
  std::vector<Object> objects_;
  std::vector<float> heap_;
  // A child's weight in the gather-up: log_amp - (cxx dx^2 + cyy dy^2 + cxy dx dy), the form
  // already divided by 2 abcor; lmin its smaller eigenvalue.
  struct ChildEllipse {
    float log_amp, mx, my, cxx, cyy, cxy, lmin;
    float form(float dx, float dy) const { return cxx * dx * dx + cyy * dy * dy + cxy * dx * dy; }
  };
  std::vector<ChildEllipse> children_;
  std::vector<int> tile_start_, tile_of_, unclaimed_, candidates_;
  std::vector<std::uint8_t> survives_;
};

}  // namespace stampede
