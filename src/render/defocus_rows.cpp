// composite_layers (defocus.h): every drop's layer spread by its disk, output row by output
// row. The layer of one drop is zero outside that drop's pixels, so each layer keeps only its
// rows from the drop's first to its last pixel, with per-row prefix sums; an output row then
// adds, for each drop that can reach it and each row of that drop's disk, the run of full
// weight (two prefix reads) and the rim's partial taps (disk_kernel.h), over the columns that
// row of the drop can reach. Nothing is done for pixels that no drop's circle reaches.
//
// Threads take bands of output rows; every output pixel is summed by one thread, in the same
// order (drop, kernel row, run then taps) whatever the number of threads, so the result does
// not depend on it.
#include "raindrop/render/defocus.h"

#include <algorithm>
#include <climits>
#include <cstdlib>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/render/disk_kernel.h"
#include "raindrop/render/layer_mix.h"
#include "raindrop/render/srgb.h"

namespace raindrop {
namespace {

// a R (linear RGB) and a in one SIMD register (GCC/Clang vector extension, as in blur.cpp).
typedef float f4 __attribute__((vector_size(16)));

// A row of the disk as the inner loop reads it: the run [lo, hi] of full weight, and the
// partial taps of the rim in mirrored pairs (the disk is symmetric: dx and -dx weigh the
// same) or alone (dx = 0).
struct SpreadRow {
  int dy = 0;
  int reach = 0;       // the largest |dx| of the row
  int lo = 1, hi = 0;  // empty when lo > hi
  int pair_begin = 0, pair_end = 0;
  float centre = 0;    // weight of a lone tap at dx = 0
};

struct TapPair {
  int dx;  // > 0: taps dx and -dx
  float w;
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
    s.reach_y = std::max(s.reach_y, std::abs(r.dy));
    s.rows.push_back(row);
  }
  return s;
}

// One drop's layer in the pinhole render: per row from its first pixel's row, the drop's
// first and last pixel, the values (a R, a) between them (zero where another drop is seen)
// and their prefix sums. Each row is stored with `pad` zeros on both sides, so that the inner
// loop reads every tap and run of an output pixel the row reaches without bounds checks.
struct Layer {
  int y0 = -1;  // -1: the drop has no pixel
  int pad = 0;  // twice the disk's reach
  std::vector<Span> extent;   // per row; first > second: no pixel on that row
  std::vector<size_t> start;  // per row: where its padded values start; its prefix sums start at start + row
  std::vector<f4> value;
  std::vector<f4> prefix;  // per row, padded length + 1 sums: 0, v0, v0 + v1, ...
  Spread spread;
  cv::Rect reach;  // the pixels of the frame its spread layer can reach
};

// Fills the layer's values from the trace and its disk; `layer.y0` and `extent` are set.
void build_layer(Layer& layer, int index, const TraceResult& traced, double diameter, cv::Size frame) {
  const SrgbTables& srgb = SrgbTables::get();
  layer.spread = make_spread(diameter);
  layer.pad = 2 * layer.spread.reach_x;
  const int rows = static_cast<int>(layer.extent.size());
  layer.start.resize(rows);
  size_t n = 0;
  int x_lo = INT_MAX, x_hi = INT_MIN;
  for (int j = 0; j < rows; ++j) {
    layer.start[j] = n;
    const Span e = layer.extent[j];
    if (e.first > e.second) continue;
    n += e.second - e.first + 1 + 2 * layer.pad;
    x_lo = std::min(x_lo, e.first);
    x_hi = std::max(x_hi, e.second);
  }
  layer.value.assign(n, f4{0, 0, 0, 0});
  layer.prefix.resize(n + rows);
  for (int j = 0; j < rows; ++j) {
    const Span e = layer.extent[j];
    f4* v = layer.value.data() + layer.start[j];
    f4* p = layer.prefix.data() + layer.start[j] + j;
    p[0] = f4{0, 0, 0, 0};
    if (e.first > e.second) continue;
    const int y = layer.y0 + j;
    const int* label = traced.label.ptr<int>(y);
    const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
    const int c0 = e.first - layer.pad;  // the column of v[0]
    for (int x = e.first; x <= e.second; ++x) {
      if (label[x] != index) continue;
      f4& out = v[x - c0];
      for (int c = 0; c < 3; ++c) out[c] = std::isfinite(rgb[x][c]) ? srgb.decode(rgb[x][c]) : 0.0f;
      out[3] = 1.0f;
    }
    const int length = e.second - e.first + 1 + 2 * layer.pad;
    for (int i = 0; i < length; ++i) p[i + 1] = p[i] + v[i];
  }
  const Spread& s = layer.spread;
  layer.reach = cv::Rect(x_lo - s.reach_x, layer.y0 - s.reach_y, x_hi - x_lo + 1 + 2 * s.reach_x,
                         rows + 2 * s.reach_y) &
                cv::Rect(0, 0, frame.width, frame.height);
}

// Adds the layer, spread, to output row y: acc[x] for x in [0, width).
void spread_row(const Layer& layer, int y, int width, f4* acc) {
  const Spread& s = layer.spread;
  const int rows = static_cast<int>(layer.extent.size());
  for (const SpreadRow& k : s.rows) {
    const int j = y + k.dy - layer.y0;
    if (j < 0 || j >= rows) continue;
    const Span e = layer.extent[j];
    if (e.first > e.second) continue;
    // v[i], p[i]: column c0 + i. The output columns this row reaches are within the disk's
    // reach of the drop's pixels, and the rows are padded by twice that, so every read below
    // stays in the row.
    const int c0 = e.first - layer.pad;
    const f4* v = layer.value.data() + layer.start[j];
    const f4* p = layer.prefix.data() + layer.start[j] + j;
    const int ia = std::max(e.first - k.reach, 0) - c0, ib = std::min(e.second + k.reach, width - 1) - c0;
    const TapPair* pairs = s.pairs.data() + k.pair_begin;
    const int n_pairs = k.pair_end - k.pair_begin;
    if (k.lo <= k.hi) {  // a row with a run has its centre in the run
      for (int i = ia; i <= ib; ++i) {
        f4 sum = s.run_weight * (p[i + k.hi + 1] - p[i + k.lo]);
        for (int t = 0; t < n_pairs; ++t) sum += pairs[t].w * (v[i + pairs[t].dx] + v[i - pairs[t].dx]);
        acc[i + c0] += sum;
      }
    } else {
      for (int i = ia; i <= ib; ++i) {
        f4 sum = k.centre * v[i];
        for (int t = 0; t < n_pairs; ++t) sum += pairs[t].w * (v[i + pairs[t].dx] + v[i - pairs[t].dx]);
        acc[i + c0] += sum;
      }
    }
  }
}

}  // namespace

DefocusedFrame composite_layers(const cv::Mat& clean, const TraceResult& traced, const Camera& camera,
                                const SceneSample& scene, const std::vector<Drop>& drops) {
  CV_Assert(clean.type() == CV_8UC3 && traced.label.size() == clean.size());
  const int W = clean.cols, H = clean.rows;
  DefocusedFrame out;
  out.coc_px.assign(drops.size(), 0.0);
  out.rainy = clean.clone();
  out.coverage = cv::Mat(clean.size(), CV_32F, cv::Scalar(0));

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
        Layer& layer = layers[d];
        if (layer.y0 < 0) layer.y0 = y;
        const size_t j = static_cast<size_t>(y - layer.y0);
        if (layer.extent.size() <= j) layer.extent.resize(j + 1, Span{INT_MAX, INT_MIN});
        layer.extent[j].first = std::min(layer.extent[j].first, x);
        layer.extent[j].second = std::max(layer.extent[j].second, x);
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
    if (layers[d].y0 >= 0) present.push_back(static_cast<int>(d));
  }
  tbb::parallel_for(size_t{0}, present.size(), [&](size_t i) {
    const int d = present[i];
    out.coc_px[d] = layer_blur_diameter(scene, drops[d], camera.fx, clean.size());
    build_layer(layers[d], d, traced, out.coc_px[d], clean.size());
  });

  int y_begin = H, y_end = 0;
  for (int d : present) {
    y_begin = std::min(y_begin, layers[d].reach.y);
    y_end = std::max(y_end, layers[d].reach.y + layers[d].reach.height);
  }
  if (y_begin >= y_end) return out;
  tbb::parallel_for(tbb::blocked_range<int>(y_begin, y_end, 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<const Layer*> active;  // in drop order: the order of the sums
    for (int d : present) {
      const cv::Rect& reach = layers[d].reach;
      if (reach.y < r.end() && reach.y + reach.height > r.begin()) active.push_back(&layers[d]);
    }
    std::vector<f4> acc(W);
    for (int y = r.begin(); y < r.end(); ++y) {
      int xa = W, xb = -1;
      for (const Layer* layer : active) {
        if (y < layer->reach.y || y >= layer->reach.y + layer->reach.height) continue;
        xa = std::min(xa, layer->reach.x);
        xb = std::max(xb, layer->reach.x + layer->reach.width - 1);
      }
      if (xa > xb) continue;
      std::fill(acc.begin() + xa, acc.begin() + xb + 1, f4{0, 0, 0, 0});
      for (const Layer* layer : active) {
        if (y >= layer->reach.y && y < layer->reach.y + layer->reach.height) spread_row(*layer, y, W, acc.data());
      }
      const auto* b = clean.ptr<cv::Vec3b>(y);
      float* coverage = out.coverage.ptr<float>(y);
      auto* rainy = out.rainy.ptr<cv::Vec3b>(y);
      for (int x = xa; x <= xb; ++x) {
        const float c[3] = {acc[x][0], acc[x][1], acc[x][2]};
        mix_layers(acc[x][3], c, b[x].val, &coverage[x], rainy[x].val);
      }
    }
  });
  return out;
}

}  // namespace raindrop
