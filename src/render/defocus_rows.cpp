// composite_layers (defocus.h): every drop's layer spread by its disk, output row by output
// row. The layer of one drop is zero outside that drop's pixels, so each layer keeps only the
// rows from the drop's first to its last pixel, padded, with per-row prefix sums; an output
// row then adds, for each drop that can reach it and each row of that drop's disk (rows dy and
// -dy together: they weigh the same), the run of full weight (two prefix reads) and the rim's
// partial taps (disk_kernel.h), over the columns those rows of the drop can reach. Circles of
// 48 to 96 px are spread so at every second or third pixel and row and interpolated between
// (kSampledDiameter); circles of 96 px and more are spread on a coarser grid of block averages
// and interpolated back (kCoarseDiameter). Nothing is done for pixels that no drop's circle
// reaches.
//
// Threads take bands of output rows (and of a sampled or coarse layer's rows of samples or
// cells); every output pixel is summed by one thread, in the same order (drop, disk row, run
// then taps) whatever the number of threads, so the result does not depend on it.
#include "raindrop/render/defocus.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/render/blur.h"
#include "raindrop/render/disk_kernel.h"
#include "raindrop/render/layer_mix.h"
#include "raindrop/render/spans.h"
#include "raindrop/render/srgb.h"
#include "pixel_vectors.h"

namespace raindrop {
namespace {

// a R (linear RGB) and a in one SIMD register (pixel_vectors.h).
using pixel_vectors::f4;
using pixel_vectors::load;

// A row of the disk as the inner loop reads it: the run [lo, hi] of full weight, and the
// partial taps of the rim in mirrored pairs (the disk is symmetric: dx and -dx weigh the
// same) or alone (dx = 0). Row dy > 0 stands for rows dy and -dy, which weigh the same.
struct SpreadRow {
  int dy = 0;  // >= 0
  int reach = 0;       // the largest |dx| of the row
  int lo = 1, hi = 0;  // empty when lo > hi
  int pair_begin = 0, pair_end = 0;
  float centre = 0;    // weight of a lone tap at dx = 0
  // Where the run's prefix sums lie from an output pixel's place in the layer's storage
  // (Rows::bind): columns hi + 1 and lo.
  int hi_at = 0, lo_at = 0;
};

struct TapPair {
  int dx;  // > 0: taps dx and -dx
  float w;
  int plus_at = 0, minus_at = 0;  // where columns dx and -dx lie (Rows::bind)
};

// The normalised disk of one drop (weights as blur_kernel's, in float).
struct Spread {
  std::vector<SpreadRow> rows;
  std::vector<TapPair> pairs;
  float run_weight = 0;  // of each tap in a run
  int reach_x = 0, reach_y = 0;
};

// A run this short is cheaper as taps (a tap is one read, a run two), and exact.
constexpr int kMinRun = 3;

Spread make_spread(double diameter) {
  Spread s;
  if (!(diameter > 0)) {  // left sharp: the identity, exactly
    SpreadRow row;
    row.centre = 1.0f;
    s.rows.push_back(row);
    return s;
  }
  const std::vector<KernelRow> rows = disk_rows(diameter, true, true);
  double total = 0;
  for (const KernelRow& r : rows) {
    if (r.run_lo <= r.run_hi) total += r.run_hi - r.run_lo + 1;
    for (const auto& [dx, w] : r.taps) total += w;
  }
  s.run_weight = static_cast<float>(1.0 / total);
  for (const KernelRow& r : rows) {
    s.reach_y = std::max(s.reach_y, std::abs(r.dy));
    if (r.dy < 0) continue;  // the disk's weights depend on |dy| only (disk_kernel.cpp): row -dy is row dy
    SpreadRow row;
    row.dy = r.dy;
    // Every tap of the row with its normalised weight, by dx; a short run becomes taps.
    std::vector<std::pair<int, float>> taps;
    if (r.run_hi - r.run_lo + 1 >= kMinRun) {
      row.lo = r.run_lo;
      row.hi = r.run_hi;
      row.reach = std::max(std::abs(r.run_lo), std::abs(r.run_hi));
    } else {
      for (int dx = r.run_lo; dx <= r.run_hi; ++dx) taps.push_back({dx, s.run_weight});
    }
    for (const auto& [dx, w] : r.taps) taps.push_back({dx, static_cast<float>(w / total)});
    row.pair_begin = static_cast<int>(s.pairs.size());
    for (const auto& [dx, w] : taps) {
      row.reach = std::max(row.reach, std::abs(dx));
      if (dx == 0) {
        row.centre = w;
      } else if (dx > 0) {
        // The disk's weights depend on |dx| only (disk_kernel.cpp), so -dx is in the row too.
        s.pairs.push_back({dx, w});
      }
    }
    row.pair_end = static_cast<int>(s.pairs.size());
    s.reach_x = std::max(s.reach_x, row.reach);
    s.rows.push_back(row);
  }
  return s;
}

// a / b rounded down (b > 0).
int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// Rows of an image that is zero outside a drop, from its first row (y0): per row the first
// and last column that may be non-zero, and the values and their prefix sums on columns
// [x0, x0 + width), which hold every row's non-zero columns with `pad` zeros on both sides
// (twice the disk's reach): the inner loop of spread_row reads every tap and run of an
// output pixel that a row reaches without bounds checks, and rows dy and -dy of the disk
// share their column offsets.
struct Rows {
  int y0 = -1;  // -1: empty
  int x0 = 0, width = 0, pad = 0;
  // Columns x0 + i, i = 0 .. width - 1, stored by their remainder mod `stride`: column i at
  // (i mod stride) * phase + i / stride of its row (phase: the entries of one remainder; a
  // value row has `phase` = ceil(width / stride), a prefix row ceil((width + 1) / stride)).
  // Outputs at every stride-th column (sampled layers) then read each tap and run end from
  // consecutive places, as the outputs at every column do with stride 1 (the plain layout).
  int stride = 1, value_phase = 0, prefix_phase = 0;
  std::vector<Span> extent;  // per row; first > second: nothing on that row
  std::vector<f4> value;     // rows x (stride * value_phase)
  // rows x (stride * prefix_phase): 0, v0, v0 + v1, ...; left uninitialised (sum_rows writes
  // every column of the rows that have pixels, the only ones read).
  std::unique_ptr<f4[]> prefix;
  Spread spread;

  bool has_row(int j) const {
    return j >= 0 && j < static_cast<int>(extent.size()) && extent[j].first <= extent[j].second;
  }
  // Zero values for the extents, with `pad` = twice the spread's reach (and a stride more, for
  // outputs rounded to the stride's grid), x0 on that grid.
  void allocate(int s = 1) {
    stride = s;
    pad = 2 * spread.reach_x + (s > 1 ? s : 0);
    int lo = INT_MAX, hi = INT_MIN;
    for (const Span& e : extent) {
      if (e.first > e.second) continue;
      lo = std::min(lo, e.first);
      hi = std::max(hi, e.second);
    }
    x0 = floor_div(lo - pad, s) * s;
    width = hi + pad + 1 - x0;
    value_phase = (width + s - 1) / s;
    prefix_phase = (width + 1 + s - 1) / s;
    value.assign(extent.size() * s * value_phase, f4{0, 0, 0, 0});
    prefix.reset(new f4[extent.size() * s * prefix_phase]);
  }
  size_t place(int i, int phase) const {
    return stride == 1 ? static_cast<size_t>(i) : static_cast<size_t>(i % stride) * phase + i / stride;
  }
  f4& at(int j, int x) { return value[static_cast<size_t>(j) * stride * value_phase + place(x - x0, value_phase)]; }
  const f4* value_row(int j) const { return value.data() + static_cast<size_t>(j) * stride * value_phase; }
  const f4* prefix_row(int j) const { return prefix.get() + static_cast<size_t>(j) * stride * prefix_phase; }
  void sum_rows() {
    for (size_t j = 0; j < extent.size(); ++j) {
      if (extent[j].first > extent[j].second) continue;
      const f4* v = value_row(static_cast<int>(j));
      f4* p = prefix.get() + j * stride * prefix_phase;
      if (stride == 1) {
        p[0] = f4{0, 0, 0, 0};
        for (int i = 0; i < width; ++i) p[i + 1] = p[i] + v[i];
        continue;
      }
      // Column i = q stride + r, walked in order without a division per column.
      f4 sum{0, 0, 0, 0};
      p[0] = sum;
      for (int i = 0, q = 0, r = 0; i < width; ++i) {
        sum = sum + v[static_cast<size_t>(r) * value_phase + q];
        if (++r == stride) r = 0, ++q;
        p[static_cast<size_t>(r) * prefix_phase + q] = sum;  // column i + 1
      }
    }
  }
  // The spread's offsets for this storage: from output column i (a multiple of the stride),
  // column i + dx lies at (i / stride) + the offset of dx.
  void bind() {
    auto at = [&](int dx, int phase) {
      const int q = floor_div(dx, stride);
      return (dx - q * stride) * phase + q;
    };
    for (SpreadRow& r : spread.rows) {
      r.hi_at = at(r.hi + 1, prefix_phase);
      r.lo_at = at(r.lo, prefix_phase);
    }
    for (TapPair& t : spread.pairs) {
      t.plus_at = at(t.dx, value_phase);
      t.minus_at = at(-t.dx, value_phase);
    }
  }
};

// Adds `rows`, spread by its disk, to output row y: acc[x] for x in [0, width).
void spread_row(const Rows& rows, int y, int width, f4* acc);

// Adds `rows` (stored with a stride s), spread by its disk, at columns u s of output row y to
// out[u - u0] for u in [u0, u0 + n).
void spread_samples(const Rows& rows, int y, int u0, int n, f4* out);

// A circle of confusion at least twice this wide is spread on a coarser grid of s x s pixel
// blocks, s = floor(diameter / kCoarseDiameter): the block averages are spread by the disk of
// diameter / s (>= kCoarseDiameter cells) and the result is interpolated back (bilinear). That
// costs O(diameter / s^3) per pixel instead of O(diameter) (at 2048 px, lens-cover's
// 180-pixel circles: 52 ms instead of 428 in RESULTS 4.1), and differs from the exact spread by what
// the extra smoothing, about s pixels wide, changes in a disk at least 48 s wide: most at the
// peak of a drop about as wide as its circle, where the spread coverage has a cone-like tip.
// Measured on lens-cover frames at 2048 px and on the tests' scenes: coverage within 0.64/255
// and the image within one level; 32 gave 1.9/255 (tests/render/test_defocus.cpp checks 1/255).
constexpr double kCoarseDiameter = 48;

int coarse_scale(double diameter) { return std::max(1, static_cast<int>(diameter / kCoarseDiameter)); }

// Circles narrower than the coarse grid's but at least twice this wide are spread exactly at
// every s-th pixel of every s-th row, s = floor(diameter / kSampledDiameter) (2 or 3), and
// interpolated between those samples (bilinear): O(diameter / s^2) per pixel. Sampled points
// are exact; between them the interpolation cuts the corners of the spread's cone-like tips
// (where a drop is about as wide as its circle), with no block average to smooth the rest as
// the coarse grid's does. Measured on the tests' scenes (tests/render/test_defocus.cpp):
// coverage within 2.8/255 and the image within two levels of the exact spread (0.15 RMS); on
// lens-cover Cityscapes frames at 1024 px, four levels at a handful of dark pixels (0.05 RMS
// over the frame); 3.3/255 where some fifty sampled drops overlap on a random frame. The layered path itself is about 6 levels RMS from the aperture reference.
// A drop that sees lifted light (highlights.h) is spread at every pixel: its bokeh's rim is as
// high as the light, and interpolation smeared it by up to 22 levels on night renders. On
// windshield drops at f/2 with the glass at 10 cm (circles of 30-125 px at 2048 px) the render
// core takes a quarter less time (RESULTS 4.63). 32 (only circles from 64 px, by 2) saved 5%;
// 16 no more than 24.
constexpr double kSampledDiameter = 24;

int sample_stride(double diameter) { return std::max(1, static_cast<int>(diameter / kSampledDiameter)); }

// One drop's layer: its pixels in the pinhole render, (a R, a) in linear light, and how it
// is spread.
struct Layer {
  Rows rows;       // scale 1 or sampled: the drop's pixels, frame coordinates; else its s x s
                   // block averages, in cells from (cell_x0, cell_y0)
  int scale = 1;
  bool sampled = false;  // scale > 1: cell (u, v) is the exact spread at pixel (u s, v s)
  // scale > 1: the spread block averages, cells_high x cells_wide from cell (cell_x0, cell_y0).
  int cell_x0 = 0, cell_y0 = 0, cells_wide = 0, cells_high = 0;
  std::vector<f4> cells;
  cv::Rect reach;  // the pixels of the frame its spread layer can reach
};

// The drop's pixel (a R, a), decoded from the trace and lifted where it was clipped; `a` is the
// trace's coverage (1 but where the tracer sampled the lens: TraceResult::coverage).
inline f4 traced_value(const cv::Vec3f& rgb, const SrgbTables& srgb, const HighlightLift& lift, float a) {
  float r[3];
  for (int c = 0; c < 3; ++c) r[c] = std::isfinite(rgb[c]) ? srgb.decode(rgb[c]) : 0.0f;
  lift.apply(r);
  return f4{a * r[0], a * r[1], a * r[2], a};
}

// Whether the highlights' lift (highlights.h) raises any of the drop's pixels above full scale.
bool lifted(const Rows& px, int index, const TraceResult& traced, const HighlightLift& lift) {
  if (!lift.active()) return false;
  const SrgbTables& srgb = SrgbTables::get();
  for (size_t j = 0; j < px.extent.size(); ++j) {
    const int y = px.y0 + static_cast<int>(j);
    const int* label = traced.label.ptr<int>(y);
    const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
    for (int x = px.extent[j].first; x <= px.extent[j].second; ++x) {
      if (label[x] != index) continue;
      const float brightest = std::max(rgb[x][0], std::max(rgb[x][1], rgb[x][2]));
      if (std::isfinite(brightest) && srgb.decode(brightest) > lift.threshold) return true;
    }
  }
  return false;
}

// Fills the layer from the trace and spreads it where it is coarse; `layer.rows.y0` and
// `extent` hold the drop's pixels (frame coordinates).
void build_layer(Layer& layer, int index, const TraceResult& traced, double diameter, const HighlightLift& lift,
                 cv::Size frame) {
  const SrgbTables& srgb = SrgbTables::get();
  Rows& px = layer.rows;
  const int n_rows = static_cast<int>(px.extent.size());
  int x_lo = INT_MAX, x_hi = INT_MIN;
  for (const Span& e : px.extent) {
    if (e.first > e.second) continue;
    x_lo = std::min(x_lo, e.first);
    x_hi = std::max(x_hi, e.second);
  }
  layer.scale = coarse_scale(diameter);
  if (layer.scale == 1) {
    // Exact, at every pixel or (sampled) at every s-th pixel of every s-th row. A layer with
    // lifted light is spread at every pixel: its spread is a bokeh disk whose rim, as high as
    // the light, interpolation would smear (on night renders, by up to 22 levels).
    const int s = lifted(px, index, traced, lift) ? 1 : sample_stride(diameter);
    layer.scale = s;
    layer.sampled = s > 1;
    px.spread = make_spread(diameter);
    px.allocate(s);
    for (int j = 0; j < n_rows; ++j) {
      const Span e = px.extent[j];
      // A row between the drop's first and last that holds none of its pixels (merged drops:
      // another's label there) keeps the empty span {INT_MAX, INT_MIN}; skipped, as the coarse
      // path below skips it, before e.first - px.x0 overflows (UBSan, lens-cover-merged).
      if (e.first > e.second) continue;
      const int* label = traced.label.ptr<int>(px.y0 + j);
      const auto* rgb = traced.color.ptr<cv::Vec3f>(px.y0 + j);
      const float* cov = traced.coverage.empty() ? nullptr : traced.coverage.ptr<float>(px.y0 + j);
      f4* row = px.value.data() + static_cast<size_t>(j) * s * px.value_phase;
      // Column x at place(x - x0): remainder r and quotient q, walked without a division.
      int r = (e.first - px.x0) % s, q = (e.first - px.x0) / s;
      for (int x = e.first; x <= e.second; ++x) {
        if (label[x] == index) row[static_cast<size_t>(r) * px.value_phase + q] = traced_value(rgb[x], srgb, lift, cov ? cov[x] : 1.0f);
        if (++r == s) r = 0, ++q;
      }
    }
    px.sum_rows();
    px.bind();
    const Spread& k = px.spread;
    layer.reach = cv::Rect(x_lo - k.reach_x, px.y0 - k.reach_y, x_hi - x_lo + 1 + 2 * k.reach_x, n_rows + 2 * k.reach_y) &
                  cv::Rect(0, 0, frame.width, frame.height);
    if (!layer.sampled || layer.reach.area() == 0) return;
    // Samples at every s-th column and row of the reach, and one beyond its last pixel.
    layer.cell_x0 = layer.reach.x / s;
    layer.cell_y0 = layer.reach.y / s;
    layer.cells_wide = (layer.reach.x + layer.reach.width - 1) / s + 2 - layer.cell_x0;
    layer.cells_high = (layer.reach.y + layer.reach.height - 1) / s + 2 - layer.cell_y0;
    layer.cells.assign(static_cast<size_t>(layer.cells_wide) * layer.cells_high, f4{0, 0, 0, 0});
    tbb::parallel_for(0, layer.cells_high, [&](int r) {
      spread_samples(px, (layer.cell_y0 + r) * s, layer.cell_x0, layer.cells_wide,
                     layer.cells.data() + static_cast<size_t>(r) * layer.cells_wide);
    });
    return;
  }
  // Coarse: cell (u, v) averages pixels [u s, u s + s) x [v s, v s + s) of the frame. The cells
  // are counted from one beyond the spread's reach, so the spread is computed whole (also
  // beyond the frame's edge, which the interpolation next to the edge reads).
  const int s = layer.scale;
  Rows cell;
  cell.spread = make_spread(diameter / s);
  const int u0 = x_lo / s, u1 = x_hi / s, v0 = px.y0 / s, v1 = (px.y0 + n_rows - 1) / s;
  layer.cell_x0 = u0 - cell.spread.reach_x - 1;
  layer.cell_y0 = v0 - cell.spread.reach_y - 1;
  layer.cells_wide = u1 - u0 + 1 + 2 * cell.spread.reach_x + 2;
  layer.cells_high = v1 - v0 + 1 + 2 * cell.spread.reach_y + 2;
  cell.y0 = v0 - layer.cell_y0;
  cell.extent.assign(v1 - v0 + 1, Span{INT_MAX, INT_MIN});
  for (int j = 0; j < n_rows; ++j) {
    const Span e = px.extent[j];
    if (e.first > e.second) continue;
    Span& c = cell.extent[(px.y0 + j) / s - v0];
    c.first = std::min(c.first, e.first / s - layer.cell_x0);
    c.second = std::max(c.second, e.second / s - layer.cell_x0);
  }
  cell.allocate();
  cell.bind();
  const float area = 1.0f / static_cast<float>(s * s);
  for (int j = 0; j < n_rows; ++j) {
    const Span e = px.extent[j];
    const int y = px.y0 + j, jc = y / s - v0;
    const int* label = traced.label.ptr<int>(y);
    const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
    const float* cov = traced.coverage.empty() ? nullptr : traced.coverage.ptr<float>(y);
    for (int x = e.first; x <= e.second; ++x) {
      if (label[x] == index)
        cell.at(jc, x / s - layer.cell_x0) += area * traced_value(rgb[x], srgb, lift, cov ? cov[x] : 1.0f);
    }
  }
  cell.sum_rows();
  layer.cells.assign(static_cast<size_t>(layer.cells_wide) * layer.cells_high, f4{0, 0, 0, 0});
  tbb::parallel_for(0, layer.cells_high, [&](int r) {
    spread_row(cell, r, layer.cells_wide, layer.cells.data() + static_cast<size_t>(r) * layer.cells_wide);
  });
  layer.rows = std::move(cell);
  // Pixel x sits at cell coordinate (x + 0.5) / s - 0.5: the interpolation reads cells
  // [0, cells_wide) for x from (cell_x0 + 0.5) s - 0.5 to (cell_x0 + cells_wide - 0.5) s - 0.5.
  auto first_pixel = [s](int c) { return static_cast<int>(std::ceil((c + 0.5) * s - 0.5)); };
  const int xa = first_pixel(layer.cell_x0), ya = first_pixel(layer.cell_y0);
  const int xb = first_pixel(layer.cell_x0 + layer.cells_wide - 1), yb = first_pixel(layer.cell_y0 + layer.cells_high - 1);
  layer.reach = cv::Rect(xa, ya, xb - xa, yb - ya) & cv::Rect(0, 0, frame.width, frame.height);
}

// Adds a sampled layer's spread, interpolated (bilinear) between its samples, to output row y
// over its reach.
void interpolate_samples(const Layer& layer, int y, f4* acc) {
  const int s = layer.scale;
  const float inv = 1.0f / static_cast<float>(s);
  const float wy = static_cast<float>(y % s) * inv;
  const f4* r0 = layer.cells.data() + static_cast<size_t>(y / s - layer.cell_y0) * layer.cells_wide;
  const f4* r1 = r0 + layer.cells_wide;
  for (int x = layer.reach.x; x < layer.reach.x + layer.reach.width; ++x) {
    const int ix = x / s - layer.cell_x0;
    const float wx = static_cast<float>(x % s) * inv;
    const f4 top = r0[ix] + wx * (r0[ix + 1] - r0[ix]), bottom = r1[ix] + wx * (r1[ix + 1] - r1[ix]);
    acc[x] += top + wy * (bottom - top);
  }
}

// Adds a coarse layer's spread, interpolated (bilinear), to output row y over its reach.
void interpolate_row(const Layer& layer, int y, f4* acc) {
  const double inv = 1.0 / layer.scale;
  const double fy = (y + 0.5) * inv - 0.5 - layer.cell_y0;
  const int iy = std::min(static_cast<int>(std::floor(fy)), layer.cells_high - 2);
  const float wy = static_cast<float>(fy - iy);
  const f4* r0 = layer.cells.data() + static_cast<size_t>(iy) * layer.cells_wide;
  const f4* r1 = r0 + layer.cells_wide;
  for (int x = layer.reach.x; x < layer.reach.x + layer.reach.width; ++x) {
    const double fx = (x + 0.5) * inv - 0.5 - layer.cell_x0;
    const int ix = std::min(static_cast<int>(std::floor(fx)), layer.cells_wide - 2);
    const float wx = static_cast<float>(fx - ix);
    const f4 top = r0[ix] + wx * (r0[ix + 1] - r0[ix]), bottom = r1[ix] + wx * (r1[ix + 1] - r1[ix]);
    acc[x] += top + wy * (bottom - top);
  }
}

// Output pixels i, i + P, ... of [i, ib) while a whole register of P pixels fits, P pixels per
// V (f4: one); returns the first pixel left. Neighbouring pixels' f4 are neighbours in memory,
// so one load serves P pixels, and each lane does the one-pixel arithmetic in its order (no
// fused multiply-add: -ffp-contract=off): every register width gives the same bits.
template <typename V, bool kPair, bool kRun>
inline __attribute__((always_inline)) int spread_wide(const SpreadRow& k, const Spread& s, const f4* a, const f4* pa,
                                                      const f4* b, const f4* pb, int i, int ib, int x0, f4* acc) {
  constexpr int P = sizeof(V) / sizeof(f4);
  const TapPair* pairs = s.pairs.data() + k.pair_begin;
  const int n_pairs = k.pair_end - k.pair_begin;
  for (; i + P <= ib; i += P) {
    V sum;
    if constexpr (kRun) {
      V hi, lo;
      load(hi, pa + i + k.hi_at);
      load(lo, pa + i + k.lo_at);
      V run = hi - lo;
      if constexpr (kPair) {
        load(hi, pb + i + k.hi_at);
        load(lo, pb + i + k.lo_at);
        run += hi - lo;
      }
      sum = s.run_weight * run;
    } else {
      V centre;
      load(centre, a + i);
      if constexpr (kPair) {
        V other;
        load(other, b + i);
        centre += other;
      }
      sum = k.centre * centre;
    }
    for (int t = 0; t < n_pairs; ++t) {
      const int plus_at = pairs[t].plus_at, minus_at = pairs[t].minus_at;
      V plus, minus;
      load(plus, a + i + plus_at);
      load(minus, a + i + minus_at);
      V taps = plus + minus;
      if constexpr (kPair) {
        load(plus, b + i + plus_at);
        load(minus, b + i + minus_at);
        taps += plus + minus;
      }
      sum += pairs[t].w * taps;
    }
    V out;
    load(out, acc + x0 + i);
    out += sum;
    __builtin_memcpy(acc + x0 + i, &out, sizeof out);
  }
  return i;
}

#if defined(__x86_64__) && defined(__GNUC__)
// Two pixels per AVX register, four per AVX-512 one, chosen when the program runs (the
// blur's choice: blur_simd_level_used, force_blur_simd_level for tests).
using pixel_vectors::f8;
using pixel_vectors::f16;
template <bool kPair, bool kRun>
__attribute__((target("avx"))) int spread_avx(const SpreadRow& k, const Spread& s, const f4* a, const f4* pa,
                                              const f4* b, const f4* pb, int i, int ib, int x0, f4* acc) {
  return spread_wide<f8, kPair, kRun>(k, s, a, pa, b, pb, i, ib, x0, acc);
}
template <bool kPair, bool kRun>
__attribute__((target("avx512f"))) int spread_avx512(const SpreadRow& k, const Spread& s, const f4* a, const f4* pa,
                                                     const f4* b, const f4* pb, int i, int ib, int x0, f4* acc) {
  return spread_wide<f16, kPair, kRun>(k, s, a, pa, b, pb, i, ib, x0, acc);
}
#endif

// One disk row (or mirrored pair of rows) over columns [ia, ib) of the layer's storage, added
// to acc[x0 + i]: a and b are the layer rows it reads (b: the mirrored row, when kPair), pa and
// pb their prefix sums.
template <bool kPair, bool kRun>
inline void spread_loop(const SpreadRow& k, const Spread& s, const f4* a, const f4* pa, const f4* b, const f4* pb,
                        int ia, int ib, int x0, f4* acc, int level) {
  int i = ia;
#if defined(__x86_64__) && defined(__GNUC__)
  if (level >= 2) i = spread_avx512<kPair, kRun>(k, s, a, pa, b, pb, i, ib, x0, acc);
  if (level == 1) i = spread_avx<kPair, kRun>(k, s, a, pa, b, pb, i, ib, x0, acc);
#endif
  (void)level;
  spread_wide<f4, kPair, kRun>(k, s, a, pa, b, pb, i, ib, x0, acc);
}

// The outputs at storage columns i s, i in [i_min, i_max] (those of the rows' reach), added to
// out[i + shift].
void spread_outputs(const Rows& layer, int y, int i_min, int i_max, int shift, f4* out) {
  const Spread& s = layer.spread;
  const int st = layer.stride;
  const int level = blur_simd_level_used();
  for (const SpreadRow& k : s.rows) {
    const int ja = y + k.dy - layer.y0, jb = y - k.dy - layer.y0;
    const bool has_a = layer.has_row(ja), has_b = k.dy > 0 && layer.has_row(jb);
    if (!has_a && !has_b) continue;
    // The output columns these rows reach, within the disk row's reach of their pixels; the
    // rows are padded by twice the disk's reach, so every read stays in the storage.
    int lo = INT_MAX, hi = INT_MIN;
    for (int j : {ja, jb}) {
      if (!(j == ja ? has_a : has_b)) continue;
      lo = std::min(lo, layer.extent[j].first);
      hi = std::max(hi, layer.extent[j].second);
    }
    // First and last output (storage columns, in strides) the rows reach.
    const int ia = std::max(-floor_div(layer.x0 - lo + k.reach, st), i_min);
    const int ib = std::min(floor_div(hi + k.reach - layer.x0, st), i_max) + 1;
    if (ia >= ib) continue;
    const int one = has_a ? ja : jb;
    const f4 *a = layer.value_row(one), *pa = layer.prefix_row(one);
    const f4 *b = has_b ? layer.value_row(jb) : a, *pb = has_b ? layer.prefix_row(jb) : pa;
    const bool run = k.lo <= k.hi;  // a row with a run has its centre in the run
    const int x0 = shift;
    if (has_a && has_b) {
      run ? spread_loop<true, true>(k, s, a, pa, b, pb, ia, ib, x0, out, level)
          : spread_loop<true, false>(k, s, a, pa, b, pb, ia, ib, x0, out, level);
    } else {
      run ? spread_loop<false, true>(k, s, a, pa, a, pa, ia, ib, x0, out, level)
          : spread_loop<false, false>(k, s, a, pa, a, pa, ia, ib, x0, out, level);
    }
  }
}

void spread_row(const Rows& layer, int y, int width, f4* acc) {
  spread_outputs(layer, y, -layer.x0, width - 1 - layer.x0, layer.x0, acc);
}

void spread_samples(const Rows& layer, int y, int u0, int n, f4* out) {
  const int first = u0 - layer.x0 / layer.stride;  // x0 is a multiple of the stride
  spread_outputs(layer, y, first, first + n - 1, -first, out);
}

}  // namespace

cv::Mat spread_layer(const cv::Mat& values, double diameter) {
  CV_Assert(values.type() == CV_32FC4 && diameter > 0);
  Rows rows;
  rows.y0 = 0;
  rows.extent.assign(values.rows, Span{0, values.cols - 1});
  rows.spread = make_spread(diameter);
  rows.allocate();
  rows.bind();
  for (int y = 0; y < values.rows; ++y) {
    const auto* v = values.ptr<cv::Vec4f>(y);
    for (int x = 0; x < values.cols; ++x) rows.at(y, x) = f4{v[x][0], v[x][1], v[x][2], v[x][3]};
  }
  rows.sum_rows();
  cv::Mat out(values.size(), CV_32FC4);
  std::vector<f4> acc(values.cols);
  for (int y = 0; y < values.rows; ++y) {
    std::fill(acc.begin(), acc.end(), f4{0, 0, 0, 0});
    spread_row(rows, y, values.cols, acc.data());
    auto* o = out.ptr<cv::Vec4f>(y);
    for (int x = 0; x < values.cols; ++x) o[x] = cv::Vec4f(acc[x][0], acc[x][1], acc[x][2], acc[x][3]);
  }
  return out;
}

DefocusedFrame composite_layers(const cv::Mat& clean, const TraceResult& traced, const Camera& camera,
                                const SceneSample& scene, const std::vector<Drop>& drops) {
  CV_Assert(clean.type() == CV_8UC3 && traced.label.size() == clean.size());
  const int W = clean.cols, H = clean.rows;
  DefocusedFrame out;
  out.coc_px.assign(drops.size(), 0.0);
  // The clean bytes and zero coverage, written row by row on all threads: the rows the layers
  // reach in the pass that composites them (while they are in the cache), the others first.
  out.rainy.create(clean.size(), CV_8UC3);
  out.coverage.create(clean.size(), CV_32F);
  auto start_row = [&](int y) {
    std::memcpy(out.rainy.ptr(y), clean.ptr(y), 3 * static_cast<size_t>(W));
    std::memset(out.coverage.ptr(y), 0, sizeof(float) * static_cast<size_t>(W));
  };

  // Each drop's first and last pixel per row, from the traced pixels (the tracer's spans, or
  // the drop pixels' box when a trace has none).
  std::vector<Layer> layers(drops.size());
  const cv::Rect all = traced.drop_box;
  const bool have_spans = static_cast<int>(traced.spans.size()) == H;
  for (int y = all.y; y < all.y + all.height; ++y) {
    const int* label = traced.label.ptr<int>(y);
    auto visit = [&](int x0, int x1) {
      for (int x = std::max(x0, all.x); x <= std::min(x1, all.x + all.width - 1); ++x) {
        const int d = label[x];
        if (d < 0) continue;
        Rows& rows = layers[d].rows;
        if (rows.y0 < 0) rows.y0 = y;
        const size_t j = static_cast<size_t>(y - rows.y0);
        if (rows.extent.size() <= j) rows.extent.resize(j + 1, Span{INT_MAX, INT_MIN});
        rows.extent[j].first = std::min(rows.extent[j].first, x);
        rows.extent[j].second = std::max(rows.extent[j].second, x);
      }
    };
    if (have_spans) {
      for (const auto& [x0, x1] : traced.spans[y]) visit(x0, x1);
    } else {
      visit(all.x, all.x + all.width - 1);
    }
  }
  std::vector<int> present;
  for (size_t d = 0; d < drops.size(); ++d) {
    if (layers[d].rows.y0 >= 0) present.push_back(static_cast<int>(d));
  }
  tbb::parallel_for(size_t{0}, present.size(), [&](size_t i) {
    const int d = present[i];
    out.coc_px[d] = layer_blur_diameter(scene, drops[d], camera.fx, clean.size());
    build_layer(layers[d], d, traced, out.coc_px[d], scene.highlights, clean.size());
  });

  int y_begin = H, y_end = 0;
  for (int d : present) {
    y_begin = std::min(y_begin, layers[d].reach.y);
    y_end = std::max(y_end, layers[d].reach.y + layers[d].reach.height);
  }
  y_begin = std::max(y_begin, 0);
  y_end = std::max(std::min(y_end, H), y_begin);
  tbb::parallel_for(tbb::blocked_range<int>(0, H, 16), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y)
      if (y < y_begin || y >= y_end) start_row(y);
  });
  if (y_begin >= y_end) return out;
  tbb::parallel_for(tbb::blocked_range<int>(y_begin, y_end, 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<const Layer*> active;  // in drop order: the order of the sums
    for (int d : present) {
      const cv::Rect& reach = layers[d].reach;
      if (reach.y < r.end() && reach.y + reach.height > r.begin()) active.push_back(&layers[d]);
    }
    std::vector<f4> acc(W);
    std::vector<Span> spans;  // the columns of row y that some layer reaches
    for (int y = r.begin(); y < r.end(); ++y) {
      start_row(y);
      spans.clear();
      for (const Layer* layer : active) {
        if (y < layer->reach.y || y >= layer->reach.y + layer->reach.height) continue;
        spans.push_back({layer->reach.x, layer->reach.x + layer->reach.width - 1});
      }
      if (spans.empty()) continue;
      merge_spans(spans);
      for (const auto& [xa, xb] : spans) std::fill(acc.begin() + xa, acc.begin() + xb + 1, f4{0, 0, 0, 0});
      for (const Layer* layer : active) {
        if (y < layer->reach.y || y >= layer->reach.y + layer->reach.height) continue;
        if (layer->scale == 1) {
          spread_row(layer->rows, y, W, acc.data());
        } else if (layer->sampled) {
          interpolate_samples(*layer, y, acc.data());
        } else {
          interpolate_row(*layer, y, acc.data());
        }
      }
      const auto* b = clean.ptr<cv::Vec3b>(y);
      float* coverage = out.coverage.ptr<float>(y);
      auto* rainy = out.rainy.ptr<cv::Vec3b>(y);
      for (const auto& [xa, xb] : spans) {
        for (int x = xa; x <= xb; ++x) {
          const float c[3] = {acc[x][0], acc[x][1], acc[x][2]};
          mix_layers(acc[x][3], c, b[x].val, scene.highlights, &coverage[x], rainy[x].val);
        }
      }
    }
  });
  return out;
}

}  // namespace raindrop
