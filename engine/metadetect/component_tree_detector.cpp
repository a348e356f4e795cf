// Source Extractor's detection from a component tree; see component_tree_detector.hpp. The rules
// (which pixels, which levels, which branches, which weights) are SEP 1.2.1's as
// ../shared/reference/sep-detection.md states them; section numbers below are that file's.
#include "engine/metadetect/component_tree_detector.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

namespace stampede {
namespace {

// Objects nearer than (a_1 + a_2) x this are tested by the cleaning (SEP's CLEAN_ZONE).
constexpr float kCleanZone = 10.0f;
// A deblending level's components are kept from this many pixels (or min_area if fewer).
constexpr int kLevelMinPixels = 3;
// The gather-up's tiles: kTile x kTile pixels share their candidate children (larger tiles: fewer
// bounds, more candidates; exact at any size).
constexpr int kTile = 16;

}  // namespace

int ComponentTreeDetector::find(int p) {
  // Path halving over the level union-find.
  int* parent = parent_.data();
  while (parent[p] != p) {
    parent[p] = parent[parent[p]];
    p = parent[p];
  }
  return p;
}

int ComponentTreeDetector::row(int p) const {
  // p / width_ by a multiplication where that is exact (p width_ < 2^32), as it is for cells.
  return row_multiplier_ ? static_cast<int>((static_cast<std::uint64_t>(p) * row_multiplier_) >> 32) : p / width_;
}

void ComponentTreeDetector::segment(std::span<const float> filtered, float threshold) {
  // Section 1: finite pixels of the filtered image strictly above the threshold, 8-connected. One raster
  // pass joins each pixel to its left and upper neighbours; roots are the smallest index.
  const int w = width_, h = height_;
  int* parent = seg_parent_.data();
  auto root = [parent](int p) {
    while (parent[p] != p) {
      parent[p] = parent[parent[p]];
      p = parent[p];
    }
    return p;
  };
  auto join = [&](int a, int b) {
    a = root(a), b = root(b);
    if (a == b) return;
    if (a < b) std::swap(a, b);
    parent[a] = b;
  };
  // The pixels above the threshold are listed as they come (raster order): the passes below visit
  // them alone, not the sky around them.
  above_.clear();
  for (int y = 0; y < h; ++y) {
    const float* row = filtered.data() + static_cast<std::size_t>(y) * w;
    int* par = parent + static_cast<std::size_t>(y) * w;
    const int* up = y > 0 ? par - w : nullptr;  // the row above
    for (int x = 0; x < w; ++x) {
      // Infinite pixels are not detected either (SEP takes them, and its sums become NaN).
      if (!(row[x] > threshold) || row[x] == std::numeric_limits<float>::infinity()) {
        par[x] = -1;
        continue;
      }
      const int p = y * w + x;
      above_.push_back(p);
      // The pixel above touches the left, upper-left and upper-right ones: joined to it alone.
      if (y > 0 && up[x] >= 0) {
        par[x] = up[x];
        continue;
      }
      par[x] = p;
      if (x > 0 && par[x - 1] >= 0) {
        par[x] = par[x - 1];
      } else if (y > 0 && x > 0 && up[x - 1] >= 0) {
        par[x] = up[x - 1];
      }
      if (y > 0 && x + 1 < w && up[x + 1] >= 0) join(p, p - w + 1);
    }
  }
  // Each segment's pixels together (in raster order), by a count per root.
  seg_roots_.clear();
  for (int p : above_) {
    const int r = root(p);
    parent[p] = r;  // every pixel straight to its root, for the fill below
    if (r == p) {
      seg_count_[p] = 0;
      seg_roots_.push_back(p);
    }
    ++seg_count_[r];
  }
  int at = 0;
  for (int r : seg_roots_) {
    seg_start_[r] = at;
    at += seg_count_[r];
    seg_count_[r] = seg_start_[r];  // becomes the fill cursor
  }
  seg_pixels_.resize(static_cast<std::size_t>(at));
  for (int p : above_) seg_pixels_[static_cast<std::size_t>(seg_count_[parent[p]]++)] = p;
}

void ComponentTreeDetector::add_pixel(int p, float v) {
  int* parent = parent_.data();
  Component* c = components_.data();
  pending_.push_back(p);
  const int y = row(p), x = p - y * width_;
  const int x_lo = x > 0 ? -1 : 0, x_hi = x + 1 < width_ ? 1 : 0;
  const int y_lo = y > 0 ? -1 : 0, y_hi = y + 1 < height_ ? 1 : 0;
  int a = -1;  // p's root as the joins go on
  for (int dy = y_lo; dy <= y_hi; ++dy)
    for (int dx = x_lo; dx <= x_hi; ++dx) {
      const int q = p + dy * width_ + dx;
      if (parent[q] < 0 || q == p || parent[q] == a) continue;
      int b = find(q);
      if (a < 0) {
        // The first neighbour's component takes p in (p alone is never the larger).
        parent[p] = a = b;
        ++c[b].size;
        c[b].flux += v;
        c[b].key = std::max(c[b].key, p);
        continue;
      }
      if (a == b) continue;
      if (c[a].size < c[b].size) std::swap(a, b);
      parent[b] = a;
      c[a].size += c[b].size;
      c[a].flux += c[b].flux;
      c[a].key = std::max(c[a].key, c[b].key);
    }
  if (a < 0) {
    parent[p] = p;
    c[p].size = 1;
    c[p].key = p;
    c[p].flux = v;
    live_.push_back(p);
  }
}

void ComponentTreeDetector::snapshot(int level, int min_node_pixels) {
  // The components of every pixel above this level's threshold: a node for each of at least
  // min_node_pixels pixels; the previous (higher) level's nodes find their parent among them.
  Component* c = components_.data();
  const int first = static_cast<int>(nodes_.size());
  std::size_t kept = 0;
  for (int r : live_) {
    if (parent_[r] != r) continue;
    live_[kept++] = r;
    if (c[r].size < min_node_pixels) {
      c[r].stamp = -1;  // no node at this level (the stamp may be an earlier image's)
      continue;
    }
    Node n;
    n.level = level;
    n.npix = c[r].size;
    n.flux = static_cast<float>(c[r].flux);
    n.rep = r;
    n.key = c[r].key;
    c[r].node = static_cast<int>(nodes_.size());
    c[r].stamp = level;
    nodes_.push_back(n);
  }
  live_.resize(kept);
  for (int i = level_first_.back(); i < first; ++i)
    nodes_[i].parent = c[find(nodes_[i].rep)].node;  // a superset of >= as many pixels: always a node here
  level_first_.push_back(first);
  kept = 0;
  for (int p : pending_) {
    const int r = find(p);
    if (c[r].stamp == level)
      assigned_[p] = c[r].node;
    else
      pending_[kept++] = p;
  }
  pending_.resize(kept);
}

void ComponentTreeDetector::deblend_segment(std::span<const int> pixels, std::span<const float> filtered,
                                            std::span<const float> raw, float threshold,
                                            const DetectionOptions& options) {
  // Section 2. Level thresholds t_k = t0 (p / t0)^(k / N), k = 1 .. N - 1, p the filtered peak.
  const int n_levels = std::max(1, options.deblend_thresholds);
  float peak = -std::numeric_limits<float>::infinity();
  double flux = 0;
  for (int p : pixels) {
    peak = std::max(peak, filtered[p]);
    flux += filtered[p];
  }
  const float root_flux = static_cast<float>(flux);
  const int first_object = static_cast<int>(objects_.size());
  outputs_.clear();
  nodes_.clear();
  if (n_levels > 1 && options.deblend_contrast < 1) build_tree(pixels, filtered, threshold, peak, root_flux, options);
  if (outputs_.empty()) {
    // One object: the segment as it is.
    objects_.emplace_back();
    objects_.back().thresh = threshold;
    for (int p : pixels) owner_[p] = first_object;
    analyse(pixels, filtered, raw, first_object, true);
    mthresh(pixels, filtered, first_object, options.min_area);
    return;
  }
  // The children's cores: each output node's subtree, whose nodes a depth-first numbering makes
  // one run [tin, tout); the pixels bucketed by their deepest node's number.
  const int root_index = static_cast<int>(nodes_.size()) - 1;
  {
    int clock = 0;
    dfs_stack_.assign(1, root_index);
    nodes_[root_index].tin = clock++;
    nodes_[root_index].cursor = nodes_[root_index].first_son;
    while (!dfs_stack_.empty()) {
      Node& nd = nodes_[dfs_stack_.back()];
      const int j = nd.cursor;
      if (j < 0) {
        nd.tout = clock;
        dfs_stack_.pop_back();
        continue;
      }
      nd.cursor = nodes_[j].next_sibling;
      nodes_[j].tin = clock++;
      nodes_[j].cursor = nodes_[j].first_son;
      dfs_stack_.push_back(j);
    }
  }
  const int n_nodes = root_index + 1;
  bucket_start_.assign(static_cast<std::size_t>(n_nodes) + 1, 0);
  for (int p : pixels) ++bucket_start_[static_cast<std::size_t>(nodes_[assigned_[p]].tin) + 1];
  for (int t = 0; t < n_nodes; ++t) bucket_start_[t + 1] += bucket_start_[t];
  bucket_cursor_.assign(bucket_start_.begin(), bucket_start_.end() - 1);
  bucket_pixels_.resize(pixels.size());
  for (int p : pixels) bucket_pixels_[static_cast<std::size_t>(bucket_cursor_[nodes_[assigned_[p]].tin]++)] = p;
  for (int p : pixels) owner_[p] = -1;
  const int n_children = static_cast<int>(outputs_.size());
  for (int c = 0; c < n_children; ++c) {
    const Node& nd = nodes_[outputs_[c]];
    objects_.emplace_back();
    objects_.back().merged = true;
    objects_.back().thresh = levels_[nd.level];
    for (int t = bucket_start_[nd.tin]; t < bucket_start_[nd.tout]; ++t) {
      owner_[bucket_pixels_[t]] = first_object + c;
      in_core_[bucket_pixels_[t]] = 1;
    }
  }
  // Each child measured on its core, at its own level's threshold (SEP's analyse without its
  // robust centre): the ellipse whose weights share out the rest.
  core_pixels_.clear();
  for (int c = 0; c < n_children; ++c) {
    const Node& nd = nodes_[outputs_[c]];
    core_pixels_.insert(core_pixels_.end(), bucket_pixels_.begin() + bucket_start_[nd.tin],
                        bucket_pixels_.begin() + bucket_start_[nd.tout]);
  }
  analyse(core_pixels_, filtered, raw, first_object, false);
  for (int c = 0; c < n_children; ++c) {
    Object& o = objects_[first_object + c];
    o.core_edge = o.edge;
  }
  gather_up(pixels, first_object, n_children, threshold);
  // The children over their final pixels, at the detection threshold, each centred on its core.
  for (int c = 0; c < n_children; ++c) objects_[first_object + c].thresh = threshold;
  analyse(pixels, filtered, raw, first_object, true);
  mthresh(pixels, filtered, first_object, options.min_area);
  for (int p : core_pixels_) in_core_[p] = 0;
}

void ComponentTreeDetector::gather_up(std::span<const int> pixels, int first_object, int n_children, float threshold) {
  // Section 2: every pixel outside the cores goes to a child. SEP draws it at random with weights
  // amp_i exp(-q_i / (2 abcor_i)) (q_i the child's ellipse's quadratic form at the pixel, terms
  // with an exponent >= 70 left out); here to the child of the largest weight, compared as
  // logarithms, the first such in the children's order; where every weight underflows (SEP: a
  // sum below 1e-31) to the child of the smallest exponent.
  children_.resize(static_cast<std::size_t>(n_children));
  for (int c = 0; c < n_children; ++c) {
    const Object& o = objects_[first_object + c];
    ChildEllipse& e = children_[c];
    const float dist = static_cast<float>(o.npix / (2 * std::numbers::pi * o.abcor * o.a * o.b));
    float amp = dist < 70.0f ? threshold * std::exp(dist) : 4.0f * o.peak;
    amp = std::min(amp, 4.0f * o.peak);
    e.log_amp = std::log(amp);
    e.mx = static_cast<float>(o.mx), e.my = static_cast<float>(o.my);
    const float half_inv = 0.5f / o.abcor;
    e.cxx = o.cxx * half_inv, e.cyy = o.cyy * half_inv, e.cxy = o.cxy * half_inv;
    // The exponent's least curvature: the smaller eigenvalue of [[cxx, cxy/2], [cxy/2, cyy]].
    const double mean = 0.5 * (e.cxx + e.cyy), diff = 0.5 * (e.cxx - e.cyy);
    const double r = std::sqrt(diff * diff + 0.25 * static_cast<double>(e.cxy) * e.cxy);
    e.lmin = static_cast<float>(std::max(0.0, mean - r));
  }
  // The unclaimed pixels by kTile x kTile tiles: in each, only the children whose largest
  // possible score there reaches the smallest score some one child is sure to give are tried.
  const int tiles_x = (width_ + kTile - 1) / kTile, tiles_y = (height_ + kTile - 1) / kTile;
  const int n_tiles = tiles_x * tiles_y;
  tile_start_.assign(static_cast<std::size_t>(n_tiles) + 1, 0);
  tile_of_.clear();
  for (int p : pixels)
    if (owner_[p] < 0) {
      const int y = row(p), x = p - y * width_;
      const int t = (y / kTile) * tiles_x + x / kTile;
      tile_of_.push_back(t);
      ++tile_start_[static_cast<std::size_t>(t) + 1];
    }
  for (int t = 0; t < n_tiles; ++t) tile_start_[t + 1] += tile_start_[t];
  bucket_cursor_.assign(tile_start_.begin(), tile_start_.end() - 1);
  unclaimed_.resize(tile_of_.size());
  {
    std::size_t u = 0;
    for (int p : pixels)
      if (owner_[p] < 0) unclaimed_[static_cast<std::size_t>(bucket_cursor_[tile_of_[u++]]++)] = p;
  }
  const float log_tiny = std::log(1e-31f);
  const float inf = std::numeric_limits<float>::infinity();
  // The bounds' allowance for float rounding, so that the pruning never drops the best child.
  auto slack = [](float score) { return 1e-3f + 1e-4f * std::abs(score); };
  for (int t = 0; t < n_tiles; ++t) {
    if (tile_start_[t] == tile_start_[t + 1]) continue;
    const float x0 = static_cast<float>((t % tiles_x) * kTile), y0 = static_cast<float>((t / tiles_x) * kTile);
    const float x1 = std::min(x0 + kTile - 1, static_cast<float>(width_ - 1));
    const float y1 = std::min(y0 + kTile - 1, static_cast<float>(height_ - 1));
    // The least score some child is sure to give every pixel of the tile (a convex form's largest
    // value over the tile is at a corner).
    float floor_score = -inf;
    for (int c = 0; c < n_children; ++c) {
      const ChildEllipse& e = children_[c];
      const float ax = x0 - e.mx, bx = x1 - e.mx, ay = y0 - e.my, by = y1 - e.my;
      const float far = std::max(std::max(e.form(ax, ay), e.form(ax, by)), std::max(e.form(bx, ay), e.form(bx, by)));
      if (far < 69.0f) floor_score = std::max(floor_score, e.log_amp - far - slack(e.log_amp - far));
    }
    candidates_.clear();
    if (floor_score > log_tiny) {
      for (int c = 0; c < n_children; ++c) {
        const ChildEllipse& e = children_[c];
        const float nx = std::max({0.0f, x0 - e.mx, e.mx - x1}), ny = std::max({0.0f, y0 - e.my, e.my - y1});
        const float near = e.lmin * (nx * nx + ny * ny);
        if (e.log_amp - near + slack(e.log_amp - near) >= floor_score) candidates_.push_back(c);
      }
    } else {
      for (int c = 0; c < n_children; ++c) candidates_.push_back(c);
    }
    for (int k = tile_start_[t]; k < tile_start_[t + 1]; ++k) {
      const int p = unclaimed_[k];
      const int py = row(p);
      const float x = static_cast<float>(p - py * width_), y = static_cast<float>(py);
      float best = -inf, nearest = inf;
      int best_child = -1, nearest_child = 0;
      for (int c : candidates_) {
        const ChildEllipse& e = children_[c];
        const float dist = e.form(x - e.mx, y - e.my);
        if (dist < 70.0f && e.log_amp - dist > best) best = e.log_amp - dist, best_child = c;
        if (dist < nearest) nearest = dist, nearest_child = c;
      }
      owner_[p] = first_object + (best_child >= 0 && best > log_tiny ? best_child : nearest_child);
    }
  }
}

void ComponentTreeDetector::build_tree(std::span<const int> pixels, std::span<const float> filtered, float threshold,
                                       float peak, float root_flux, const DetectionOptions& options) {
  const int n_levels = options.deblend_thresholds;
  levels_.assign(static_cast<std::size_t>(n_levels), threshold);
  for (int k = 1; k < n_levels; ++k)
    levels_[k] = peak > 0 ? static_cast<float>(threshold * std::pow(static_cast<double>(peak) / threshold,
                                                                    static_cast<double>(k) / n_levels))
                          : threshold;
  // The pixels by level band: band k holds those above t_k and not above t_(k+1) (a count of the
  // levels below the value: branch-free, vectorised).
  const float* lv = levels_.data();
  pixel_band_.resize(pixels.size());
  band_count_.assign(static_cast<std::size_t>(n_levels) + 1, 0);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const float v = filtered[pixels[i]];
    int k = 0;
    for (int j = 1; j < n_levels; ++j) k += lv[j] < v;
    pixel_band_[i] = static_cast<std::uint8_t>(k);
    ++band_count_[static_cast<std::size_t>(k) + 1];
  }
  for (int k = 0; k < n_levels; ++k) band_count_[k + 1] += band_count_[k];
  band_order_.resize(pixels.size());
  bucket_cursor_.assign(band_count_.begin(), band_count_.end() - 1);
  for (std::size_t i = 0; i < pixels.size(); ++i)
    band_order_[static_cast<std::size_t>(bucket_cursor_[pixel_band_[i]]++)] = pixels[i];
  // From the top level down: each band's pixels joined to their neighbours already in, then the
  // level's components recorded.
  const int min_node_pixels = std::min(options.min_area, kLevelMinPixels);
  live_.clear();
  pending_.clear();
  level_first_.assign(1, 0);
  for (int k = n_levels - 1; k >= 1; --k) {
    for (int i = band_count_[k]; i < band_count_[k + 1]; ++i) add_pixel(band_order_[i], filtered[band_order_[i]]);
    snapshot(k, min_node_pixels);
  }
  // Level 0: the segment itself.
  const int root_index = static_cast<int>(nodes_.size());
  for (int i = level_first_.back(); i < root_index; ++i) nodes_[i].parent = root_index;
  Node root;
  root.npix = static_cast<int>(pixels.size());
  root.flux = root_flux;
  root.rep = pixels[0];
  nodes_.push_back(root);
  level_first_.push_back(root_index);
  for (int i = band_count_[0]; i < band_count_[1]; ++i) assigned_[band_order_[i]] = root_index;
  for (int p : pending_) assigned_[p] = root_index;
  for (int p : pixels) parent_[p] = -1;  // ready for the next segment
  // level_first_[i] starts level N - i (i = 1 .. N - 1); level 0 is the root alone.
  auto level_begin = [&](int level) { return level_first_[static_cast<std::size_t>(n_levels - level)]; };
  auto level_end = [&](int level) {
    return level == 0 ? root_index + 1 : level_first_[static_cast<std::size_t>(n_levels - level + 1)];
  };
  // Each level's nodes in SEP's order: by their parent's rank, then by completion in the scan.
  node_remap_.resize(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) node_remap_[i] = static_cast<int>(i);
  for (int level = 1; level < n_levels; ++level) {
    const int b = level_begin(level), e = level_end(level);
    sort_index_.resize(static_cast<std::size_t>(e - b));
    for (int i = b; i < e; ++i) sort_index_[i - b] = i;
    std::sort(sort_index_.begin(), sort_index_.end(), [&](int x, int y) {
      const Node &nx = nodes_[x], &ny = nodes_[y];
      const int px = nodes_[node_remap_[nx.parent]].order, py = nodes_[node_remap_[ny.parent]].order;
      if (px != py) return px < py;
      return nx.key < ny.key;
    });
    sorted_nodes_.resize(sort_index_.size());
    for (std::size_t r = 0; r < sort_index_.size(); ++r) {
      sorted_nodes_[r] = nodes_[sort_index_[r]];
      sorted_nodes_[r].order = static_cast<int>(r);
      node_remap_[sort_index_[r]] = b + static_cast<int>(r);
    }
    std::copy(sorted_nodes_.begin(), sorted_nodes_.end(), nodes_.begin() + b);
  }
  for (int i = 0; i < root_index; ++i) nodes_[i].parent = node_remap_[nodes_[i].parent];
  for (int p : pixels) assigned_[p] = node_remap_[assigned_[p]];
  // Sons lists in order.
  for (Node& nd : nodes_) nd.first_son = -1, nd.next_sibling = -1, nd.ok = true;
  for (int i = root_index - 1; i >= 0; --i) {
    Node& c = nodes_[i];
    c.next_sibling = nodes_[c.parent].first_son;
    nodes_[c.parent].first_son = i;
  }
  // Top-down cut (section 2, contrast): a node with >= 2 significant sons is split; each
  // significant son with no split below it is a child of the output.
  const double value0 = static_cast<double>(root_flux) * options.deblend_contrast;
  auto significant = [&](const Node& c) {
    return static_cast<double>(c.flux - levels_[c.level] * static_cast<float>(c.npix)) > value0;
  };
  for (int level = n_levels - 2; level >= 0; --level)
    for (int i = level_begin(level); i < level_end(level); ++i) {
      Node& nd = nodes_[i];
      int m = 0;
      for (int j = nd.first_son; j >= 0; j = nodes_[j].next_sibling) {
        m += significant(nodes_[j]);
        nd.ok = nd.ok && nodes_[j].ok;
      }
      if (m > 1) {
        for (int j = nd.first_son; j >= 0; j = nodes_[j].next_sibling)
          if (nodes_[j].ok && significant(nodes_[j])) outputs_.push_back(j);
        nd.ok = false;
      }
    }
  if (nodes_[root_index].ok) outputs_.clear();
}

void ComponentTreeDetector::analyse(std::span<const int> pixels, std::span<const float> filtered,
                                    std::span<const float> raw, int first, bool final) {
  // SEP's preanalyse and analyse (section 4) of objects [first, end) over the pixels they own;
  // final: a merged object centred on its core (SEP's robust analyse).
  const int end = static_cast<int>(objects_.size());
  for (int i = first; i < end; ++i) {
    Object& o = objects_[i];
    o.npix = 0, o.cflux_sum = 0, o.peak = -std::numeric_limits<float>::infinity();
    o.xmin = o.ymin = std::numeric_limits<int>::max(), o.xmax = o.ymax = -1;
    o.sx = o.sy = o.sxx = o.syy = o.sxy = 0, o.area2 = 0, o.raw_flux = 0, o.raw_above = 0, o.edge = false;
  }
  for (int p : pixels) {
    const int i = owner_[p];
    if (i < first) continue;
    Object& o = objects_[i];
    const float v = filtered[p];
    const int y = row(p), x = p - y * width_;
    const double dv = v, dx = x, dy = y;
    ++o.npix;
    o.cflux_sum += dv;
    o.sx += dv * dx, o.sy += dv * dy;
    o.sxx += dv * dx * dx, o.syy += dv * dy * dy, o.sxy += dv * dx * dy;
    o.peak = std::max(o.peak, v);
    o.xmin = std::min(o.xmin, x), o.xmax = std::max(o.xmax, x);
    o.ymin = std::min(o.ymin, y), o.ymax = std::max(o.ymax, y);
    o.raw_flux += raw[p];
    o.raw_above += raw[p] > o.thresh;
  }
  // SEP's area2 (pixels above the mean of threshold and peak), for abcor.
  for (int i = first; i < end; ++i) {
    Object& o = objects_[i];
    o.cflux = static_cast<float>(o.cflux_sum);
    o.half_peak = 0.5 * (static_cast<double>(o.thresh) + o.peak);
    o.edge = o.xmin == 0 || o.ymin == 0 || o.xmax == width_ - 1 || o.ymax == height_ - 1;
  }
  for (int p : pixels) {
    const int i = owner_[p];
    if (i >= first) objects_[i].area2 += filtered[p] > objects_[i].half_peak;
  }
  for (int i = first; i < end; ++i) {
    Object& o = objects_[i];
    if (o.npix == 0) continue;
    // SEP's moments about the object's corner (xmin, ymin), over the float flux rv, from the sums
    // about the origin.
    const double rv = o.cflux, x0 = o.xmin, y0 = o.ymin, sv = o.cflux_sum;
    const double sx = o.sx - x0 * sv, sy = o.sy - y0 * sv;
    const double sxx = o.sxx - 2 * x0 * o.sx + x0 * x0 * sv, syy = o.syy - 2 * y0 * o.sy + y0 * y0 * sv;
    const double sxy = o.sxy - x0 * o.sy - y0 * o.sx + x0 * y0 * sv;
    double xm = sx / rv, ym = sy / rv, xm2, ym2, xym;
    if (final && o.merged) {
      const double xn = o.mx - x0, yn = o.my - y0;  // the core's barycentre
      xm2 = sxx / rv + xn * xn - 2 * xm * xn;
      ym2 = syy / rv + yn * yn - 2 * ym * yn;
      xym = sxy / rv + xn * yn - xm * yn - xn * ym;
      xm = xn, ym = yn;
    } else {
      xm2 = sxx / rv - xm * xm;
      ym2 = syy / rv - ym * ym;
      xym = sxy / rv - xm * ym;
    }
    double det = xm2 * ym2 - xym * xym;
    o.singular = det < 0.00694;
    if (o.singular) {
      xm2 += 0.0833333, ym2 += 0.0833333;
      det = xm2 * ym2 - xym * xym;
    }
    const double diff = xm2 - ym2, root = std::sqrt(0.25 * diff * diff + xym * xym), mean = 0.5 * (xm2 + ym2);
    o.mx = xm + x0, o.my = ym + y0;
    o.a = static_cast<float>(std::sqrt(mean + root));
    o.b = static_cast<float>(std::sqrt(mean - root));
    o.cxx = static_cast<float>(ym2 / det);
    o.cyy = static_cast<float>(xm2 / det);
    o.cxy = static_cast<float>(-2 * xym / det);
    // Every pixel is above the threshold: SEP's dnpix is npix.
    const double thresh2 = o.half_peak, darea = o.area2 - o.npix;
    const double t1t2 = o.thresh / thresh2;
    o.abcor = 1.0f;
    if (t1t2 > 0) {
      o.abcor = static_cast<float>((darea < 0 ? darea : -1.0) /
                                   (2 * std::numbers::pi * std::log(t1t2 < 1 ? t1t2 : 0.99) * o.a * o.b));
      o.abcor = std::min(o.abcor, 1.0f);
    }
  }
}

void ComponentTreeDetector::mthresh(std::span<const int> pixels, std::span<const float> filtered, int first,
                                    int min_area) {
  // The cleaning's mthresh (section 3), as SEP's heap selection gives it over each object's pixel
  // list: the first min_area values (above the threshold) kept unsorted, the next one skipped and
  // the kept ones sorted, then each later value above the smallest replaces it: the min_area-th
  // largest but for the skipped one, or with exactly min_area pixels the first one's. SEP's list
  // holds a segment's pixels in scan order, a deblended child's core's before its gathered
  // pixels: here in raster order, the cores' first.
  const int end = static_cast<int>(objects_.size());
  const std::size_t m = static_cast<std::size_t>(min_area);
  heap_.resize(static_cast<std::size_t>(end - first) * m);
  for (int i = first; i < end; ++i) objects_[i].heap_count = min_area;
  auto take = [&](int p) {
    const int i = owner_[p];
    Object& o = objects_[i];
    float* heap = heap_.data() + static_cast<std::size_t>(i - first) * m;
    const float t = filtered[p] - o.thresh;
    if (o.heap_count > 0) {
      heap[min_area - o.heap_count] = t;
    } else if (o.heap_count == 0) {
      std::sort(heap, heap + min_area);
    } else if (t > heap[0]) {
      // Sift down a min-heap.
      heap[0] = t;
      for (std::size_t j = 0;;) {
        std::size_t k = 2 * j + 1;
        if (k >= m) break;
        if (k + 1 < m && heap[k + 1] < heap[k]) ++k;
        if (heap[j] <= heap[k]) break;
        std::swap(heap[j], heap[k]);
        j = k;
      }
    }
    --o.heap_count;
  };
  for (int p : pixels)
    if (owner_[p] >= first && in_core_[p]) take(p);
  for (int p : pixels)
    if (owner_[p] >= first && !in_core_[p]) take(p);
  for (int i = first; i < end; ++i) {
    Object& o = objects_[i];
    o.mthresh = o.npix < min_area ? 0.0f : heap_[static_cast<std::size_t>(i - first) * m];
  }
}

void ComponentTreeDetector::clean(double beta) {
  // Section 3: a fainter object within (a_1 + a_2) x 10 of a brighter one is removed where the
  // brighter's Moffat-like extrapolation exceeds its mthresh; in list order, as SEP.
  const std::size_t n = objects_.size();
  survives_.assign(n, 1);
  auto profile = [beta](const Object& o, double& amp, double& alpha) {
    const double unit = std::numbers::pi * o.a * o.b;
    amp = o.cflux / (2 * unit * o.abcor);
    alpha = (std::pow(amp / o.thresh, 1.0 / beta) - 1) * unit / o.npix;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!survives_[i]) continue;
    const Object& o1 = objects_[i];
    double amp1, alpha1;
    profile(o1, amp1, alpha1);
    for (std::size_t j = i + 1; j < n; ++j) {
      if (!survives_[j]) continue;
      const Object& o2 = objects_[j];
      const float dx = static_cast<float>(o1.mx - o2.mx), dy = static_cast<float>(o1.my - o2.my);
      float rlim = o1.a + o2.a;
      rlim *= rlim;
      if (dx * dx + dy * dy > rlim * kCleanZone * kCleanZone) continue;
      if (o2.cflux < o1.cflux) {
        const double val = 1 + alpha1 * (o1.cxx * dx * dx + o1.cyy * dy * dy + o1.cxy * dx * dy);
        if (val > 1.0 && static_cast<float>(val < 1e10 ? amp1 * std::pow(val, -beta) : 0.0) > o2.mthresh)
          survives_[j] = 0;
      } else {
        double amp2, alpha2;
        profile(o2, amp2, alpha2);
        const double val = 1 + alpha2 * (o2.cxx * dx * dx + o2.cyy * dy * dy + o2.cxy * dx * dy);
        if (val > 1.0 && static_cast<float>(val < 1e10 ? amp2 * std::pow(val, -beta) : 0.0) > o1.mthresh)
          survives_[i] = 0;
      }
    }
  }
}

void ComponentTreeDetector::detect(std::span<const float> filtered, std::span<const float> raw, int width,
                                   int height, float threshold, const DetectionOptions& options,
                                   std::vector<Detection>* out) {
  out->clear();
  const std::size_t n = static_cast<std::size_t>(width) * height;
  if (width != width_ || height != height_ || seg_parent_.size() != n) {
    width_ = width, height_ = height;
    const std::uint64_t w = static_cast<std::uint64_t>(width);
    row_multiplier_ = w * n < (std::uint64_t{1} << 32) ? ((std::uint64_t{1} << 32) + w - 1) / w : 0;
    seg_parent_.assign(n, -1);
    seg_count_.assign(n, 0), seg_start_.assign(n, 0);
    above_.reserve(n);
    parent_.assign(n, -1);
    components_.assign(n, Component{});
    assigned_.assign(n, 0), owner_.assign(n, -1), in_core_.assign(n, 0);
  }
  segment(filtered, threshold);
  // Segments in the order Lutz's scan completes them: by their last pixel in raster order.
  std::sort(seg_roots_.begin(), seg_roots_.end(), [&](int a, int b) {
    return seg_pixels_[seg_count_[a] - 1] < seg_pixels_[seg_count_[b] - 1];  // seg_count_: each one's end
  });
  objects_.clear();
  for (int r : seg_roots_) {
    const std::span<const int> pixels(seg_pixels_.data() + seg_start_[r],
                                      static_cast<std::size_t>(seg_count_[r] - seg_start_[r]));
    if (static_cast<int>(pixels.size()) < options.min_area) continue;
    deblend_segment(pixels, filtered, raw, threshold, options);
  }
  if (options.clean) clean(options.clean_param);
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (options.clean && !survives_[i]) continue;
    const Object& o = objects_[i];
    Detection d;
    d.x = o.mx, d.y = o.my;
    d.isophotal_area = o.raw_above;
    d.flux = o.raw_flux;
    d.xmin = o.xmin, d.xmax = o.xmax, d.ymin = o.ymin, d.ymax = o.ymax;
    d.sep_flags = (o.merged ? kDetectionMerged : 0) | ((o.merged ? o.core_edge : o.edge) ? kDetectionTruncated : 0) |
                  (o.singular ? kDetectionSingular : 0);
    out->push_back(d);
  }
}

}  // namespace stampede
