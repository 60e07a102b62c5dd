#include "raindrop/render/blur.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/render/disk_kernel.h"
#include "raindrop/render/scratch_pool.h"
#include "raindrop/render/spans.h"
#include "pixel_vectors.h"

namespace raindrop {
namespace {

using Spans = std::vector<std::vector<std::pair<int, int>>>;

using pixel_vectors::f4;
using pixel_vectors::load;

// A buffer of f4 left uninitialised (every element is written before it is read), from the
// scratch pool: tens of megabytes per frame, whose fresh pages would cost more than the
// blur of small drops.
class F4Buffer {
 public:
  F4Buffer() = default;
  explicit F4Buffer(size_t n) : bytes_(scratch_bytes(n * sizeof(f4))), size_(n) {}
  f4* data() { return reinterpret_cast<f4*>(bytes_.get()); }
  const f4* data() const { return reinterpret_cast<const f4*>(bytes_.get()); }
  bool empty() const { return size_ == 0; }
  f4& operator[](size_t i) { return data()[i]; }
  const f4& operator[](size_t i) const { return data()[i]; }

 private:
  ScratchBytes bytes_;
  size_t size_ = 0;
};

// The window of the frame the blur reads: the traced colour inside drops, the clean pixel
// outside, and per-row prefix sums of it (prefix[y][x] = sum of rgb[y][0..x-1]).
struct Source {
  int x0, y0, w, h;
  F4Buffer rgb;     // h x w, filled only inside `intervals`
  F4Buffer prefix;  // h x (w + 1): prefix sums restarting at each interval's start
  // Per row, the x-intervals (absolute, inclusive) the blur can read: lookups for a drop
  // pixel never leave the interval that holds it.
  std::vector<std::vector<std::pair<int, int>>> intervals;
  const f4* rgb_row(int y) const { return rgb.data() + static_cast<size_t>(y - y0) * w - x0; }
  // prefix_row(y)[x] = sum of rgb over columns x0 .. x-1 (valid for x0 <= x <= x0 + w).
  const f4* prefix_row(int y) const { return prefix.data() + static_cast<size_t>(y - y0) * (w + 1) - x0; }
};

// The union of two sorted lists of disjoint spans, merged (touching spans joined), in one pass.
std::vector<std::pair<int, int>> unite(const std::vector<std::pair<int, int>>& a, const std::vector<std::pair<int, int>>& b) {
  std::vector<std::pair<int, int>> out;
  out.reserve(a.size() + b.size());
  size_t i = 0, j = 0;
  while (i < a.size() || j < b.size()) {
    const auto& next = j == b.size() || (i < a.size() && a[i] < b[j]) ? a[i++] : b[j++];
    if (!out.empty() && next.first <= out.back().second + 1) {
      out.back().second = std::max(out.back().second, next.second);
    } else {
      out.push_back(next);
    }
  }
  return out;
}

}  // namespace

// Per row y of `box`, the part of it that the blur of drop pixels can read: the traced spans
// of rows y - reach .. y + reach, widened by `reach` and clipped to the box, merged. Without
// spans: the row. Each window's union is that of two running unions (as van Herk and
// Gil-Werman take running maxima): in blocks of 2 reach + 1 rows, the union from each row to
// its block's end and from its block's start to each row; a window starts in one block and
// ends in the next (or at its end), so it is a union from its first row to that block's end
// with a union from the next block's start to its last row.
std::vector<std::vector<Span>> blur_read_intervals(const Spans* spans, int reach, const cv::Rect& box) {
  const int lo = box.x, hi = box.x + box.width - 1;
  std::vector<std::vector<std::pair<int, int>>> out(box.height);
  if (!spans) {
    for (auto& row : out) row = {{lo, hi}};
    return out;
  }
  // Rows box.y - reach .. box.y + box.height - 1 + reach, as v = 0 .. n - 1 (empty outside the frame).
  const int first = box.y - reach, n = box.height + 2 * reach, block = 2 * reach + 1;
  const int frame_rows = static_cast<int>(spans->size());
  std::vector<std::vector<std::pair<int, int>>> widened(n), to_end(n), from_start(n);
  tbb::parallel_for(tbb::blocked_range<int>(0, (n + block - 1) / block), [&](const tbb::blocked_range<int>& r) {
    for (int b = r.begin(); b < r.end(); ++b) {
      const int v0 = b * block, v1 = std::min(n, v0 + block);
      for (int v = v0; v < v1; ++v) {
        const int y = first + v;
        if (y < 0 || y >= frame_rows) continue;
        for (const auto& [a, e] : (*spans)[y]) {
          const int ia = std::max(lo, a - reach), ib = std::min(hi, e + reach);
          if (ia <= ib) widened[v].push_back({ia, ib});
        }
        merge_spans(widened[v]);  // spans may touch once widened
      }
      for (int v = v0; v < v1; ++v) from_start[v] = v == v0 ? widened[v] : unite(from_start[v - 1], widened[v]);
      for (int v = v1 - 1; v >= v0; --v) to_end[v] = v == v1 - 1 ? widened[v] : unite(widened[v], to_end[v + 1]);
    }
  });
  // Row j of the box: window v = j .. j + 2 reach.
  tbb::parallel_for(tbb::blocked_range<int>(0, box.height, 16), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int last = j + 2 * reach;
      out[j] = j % block == 0 ? from_start[last] : unite(to_end[j], from_start[last]);
    }
  });
  return out;
}

namespace {

Source make_source(const cv::Mat& clean, const cv::Mat& label, const cv::Mat& color, const cv::Rect& box,
                   bool prefix, const Spans* spans, int reach) {
  Source s{box.x, box.y, box.width, box.height, F4Buffer(static_cast<size_t>(box.width) * box.height), {}, {}};
  if (prefix) s.prefix = F4Buffer(static_cast<size_t>(box.width + 1) * box.height);
  s.intervals = blur_read_intervals(spans, reach, box);
  tbb::parallel_for(tbb::blocked_range<int>(0, box.height, 16), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = box.y + j;
      const auto* c8 = clean.ptr<cv::Vec3b>(y);
      const int* lab = label.ptr<int>(y);
      const auto* col = color.ptr<cv::Vec3f>(y);
      f4* dst = s.rgb.data() + static_cast<size_t>(j) * box.width - box.x;
      f4* p = prefix ? s.prefix.data() + static_cast<size_t>(j) * (box.width + 1) - box.x : nullptr;
      constexpr float k = 1.0f / 255.0f;
      auto source = [&](int x) {
        return lab[x] >= 0 ? f4{col[x][0], col[x][1], col[x][2], 0.f} : f4{c8[x][0] * k, c8[x][1] * k, c8[x][2] * k, 0.f};
      };
      for (const auto& [a, b] : s.intervals[j]) {
        if (!p) {
          for (int x = a; x <= b; ++x) dst[x] = source(x);
          continue;
        }
        // One pass: the running sum's chain of additions overlaps the conversion.
        f4 sum{0, 0, 0, 0};
        p[a] = sum;
        for (int x = a; x <= b; ++x) {
          const f4 v = source(x);
          dst[x] = v;
          sum = sum + v;
          p[x + 1] = sum;
        }
      }
    }
  });
  return s;
}

// Writes `out` (one f4 per mask_box pixel, drop pixels only) back into `color`.
void store(const F4Buffer& out, const cv::Mat& label, cv::Mat& color, const cv::Rect& mask_box) {
  for (int j = 0; j < mask_box.height; ++j) {
    const int y = mask_box.y + j;
    const int* lab = label.ptr<int>(y) + mask_box.x;
    const f4* o = out.data() + static_cast<size_t>(j) * mask_box.width;
    auto* c = color.ptr<cv::Vec3f>(y) + mask_box.x;
    for (int i = 0; i < mask_box.width; ++i) {
      if (lab[i] >= 0) c[i] = cv::Vec3f(o[i][0], o[i][1], o[i][2]);
    }
  }
}

// The kernel flattened for the inner loop: full-weight runs (prefix-sum differences) and
// partial taps, each with the index of its kernel row.
struct Run { int row, lo, hi; };
struct Tap { int row, dx; float w; };

// What the inner loop reads for one row of drop pixels.
struct RowKernel {
  const std::vector<Run>& runs;
  const std::vector<Tap>& taps;
  const f4* const* prefix_rows;  // per kernel row
  const f4* const* rgb_rows;     // per kernel row
  float inv_total;
};


// Pixels [x, x + A * P) of a row, P pixels per V (f4: one, the SSE2 path), A registers at a
// time: A independent sums instead of one chain of dependent additions per pixel (which waits
// on each addition's latency). Each pixel adds the same terms in the same order (runs, then
// taps, in kernel order), whatever V and A, so the result is the same to the bit.
template <typename V, int A>
inline __attribute__((always_inline)) void sum_wide(const RowKernel& k, int x, cv::Vec3f* dst) {
  constexpr int P = sizeof(V) / sizeof(f4);
  V acc[A];
  for (int a = 0; a < A; ++a) acc[a] = V{};
  for (const Run& run : k.runs) {
    const f4* hi = k.prefix_rows[run.row] + x + run.hi;
    const f4* lo = k.prefix_rows[run.row] + x + run.lo;
    for (int a = 0; a < A; ++a) {
      V h, l;
      load(h, hi + a * P);
      load(l, lo + a * P);
      acc[a] += h - l;
    }
  }
  for (const Tap& tap : k.taps) {
    const f4* src_px = k.rgb_rows[tap.row] + x + tap.dx;
    for (int a = 0; a < A; ++a) {
      V v;
      load(v, src_px + a * P);
      acc[a] += tap.w * v;
    }
  }
  for (int a = 0; a < A; ++a) {
    const V o = acc[a] * k.inv_total;
    for (int q = 0; q < P; ++q) dst[x + a * P + q] = cv::Vec3f(o[4 * q], o[4 * q + 1], o[4 * q + 2]);
  }
}

// The same sums as sum_wide<V, A>, register a taking the P pixels from xs[a]: a run's last
// pixels, which do not fill A registers side by side, are summed A registers at a time by
// overlapping the pixels before them (summed again to the same values, since each pixel adds the
// same terms in the same order whichever register holds it) instead of in fewer registers, whose
// chains of dependent additions leave the adder waiting (or one pixel per register, P times slower).
template <typename V, int A>
inline __attribute__((always_inline)) void sum_at(const RowKernel& k, const int* xs, cv::Vec3f* dst) {
  constexpr int P = sizeof(V) / sizeof(f4);
  V acc[A];
  for (int a = 0; a < A; ++a) acc[a] = V{};
  for (const Run& run : k.runs) {
    const f4* hi = k.prefix_rows[run.row] + run.hi;
    const f4* lo = k.prefix_rows[run.row] + run.lo;
    for (int a = 0; a < A; ++a) {
      V h, l;
      load(h, hi + xs[a]);
      load(l, lo + xs[a]);
      acc[a] += h - l;
    }
  }
  for (const Tap& tap : k.taps) {
    const f4* src_px = k.rgb_rows[tap.row] + tap.dx;
    for (int a = 0; a < A; ++a) {
      V v;
      load(v, src_px + xs[a]);
      acc[a] += tap.w * v;
    }
  }
  for (int a = 0; a < A; ++a) {
    const V o = acc[a] * k.inv_total;
    for (int q = 0; q < P; ++q) dst[xs[a] + q] = cv::Vec3f(o[4 * q], o[4 * q + 1], o[4 * q + 2]);
  }
}

// Pixels [x, end) (a run starting at `start` <= x) not left to the caller: whole groups of A
// registers of P pixels, then the rest as one more group overlapping the pixels before it
// (sum_at). Returns the first pixel left: `end`, or x where the run is narrower than P.
template <typename V, int A>
inline __attribute__((always_inline)) int blur_span_groups(const RowKernel& k, int start, int x, int end,
                                                           cv::Vec3f* dst) {
  constexpr int P = sizeof(V) / sizeof(f4), G = A * P;
  if (end - start < P) return x;
  for (; x + G <= end; x += G) sum_wide<V, A>(k, x, dst);
  if (x == end) return end;
  // The last group: from G pixels before the end, or from the run's start where it is narrower.
  const int base = std::max(start, end - G);
  int xs[A];
  for (int a = 0; a < A; ++a) xs[a] = base + std::min(a * P, end - P - base);
  sum_at<V, A>(k, xs, dst);
  return end;
}

#if defined(__x86_64__) && defined(__GNUC__)
// Wider registers hold several pixels' f4 side by side (AVX: 2, AVX-512: 4; pixel_vectors.h):
// every lane does the SSE2 path's arithmetic in its order, so the same bits with half or a
// quarter of the loads and arithmetic instructions. Chosen at run time (blur_simd_level), so
// one binary runs everywhere.
using pixel_vectors::f8;
using pixel_vectors::f16;

// Each blurs pixels x, x+1, ... of [x, end) in blocks of 8 and returns the first it left.
// Four registers at a time: each register's sum is a chain of dependent additions, and fewer
// chains leave the adder waiting on their latency.
__attribute__((target("avx"))) int blur_span_avx(const RowKernel& k, int x, int end, cv::Vec3f* dst) {
  return blur_span_groups<f8, 4>(k, x, x, end, dst);
}
__attribute__((target("avx512f"))) int blur_span_avx512(const RowKernel& k, int x, int end, cv::Vec3f* dst) {
  return blur_span_groups<f16, 4>(k, x, x, end, dst);
}
#endif

// The widest path this processor has, unless a test forced one (force_blur_simd_level).
std::atomic<int> forced_simd_level{-1};

int simd_level() {
  const int forced = forced_simd_level.load(std::memory_order_relaxed);
  return forced >= 0 ? std::min(forced, blur_simd_level()) : blur_simd_level();
}

int blur_span_wide(int level, const RowKernel& k, int x, int end, cv::Vec3f* dst) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (level >= 2) return blur_span_avx512(k, x, end, dst);
  if (level == 1) return blur_span_avx(k, x, end, dst);
#endif
  (void)level, (void)k, (void)end, (void)dst;
  return x;
}

// `spans` (optional): per frame row, x-intervals holding every drop pixel; only they are scanned
// for drop pixels (without them, the mask box's whole row, most of which is not a drop).
void blur_rows(const Source& src, const cv::Mat& label, cv::Mat& color, const cv::Rect& mask_box,
               const std::vector<KernelRow>& kernel, const Spans* spans) {
  const int W = label.cols, H = label.rows;
  std::vector<Run> runs;
  std::vector<Tap> taps;
  int reach_x = 0, reach_y = 0;
  float total = 0;
  for (size_t k = 0; k < kernel.size(); ++k) {
    const KernelRow& row = kernel[k];
    reach_y = std::max(reach_y, std::abs(row.dy));
    if (row.run_lo <= row.run_hi) {
      runs.push_back({static_cast<int>(k), row.run_lo, row.run_hi + 1});
      reach_x = std::max({reach_x, std::abs(row.run_lo), std::abs(row.run_hi)});
      total += static_cast<float>(row.run_hi - row.run_lo + 1);
    }
    for (const auto& [dx, w] : row.taps) {
      taps.push_back({static_cast<int>(k), dx, w});
      reach_x = std::max(reach_x, std::abs(dx));
      total += w;
    }
  }
  const float inv_total = 1.0f / total;
  // Away from the frame border, pixels are summed 8 at a time (sum_wide).
  constexpr int kBlock = 8;
  const int level = simd_level();
  // Results go straight into `color`: the blur reads only `src`, a copy.
  tbb::parallel_for(tbb::blocked_range<int>(0, mask_box.height, 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<const f4*> prefix_rows(kernel.size()), rgb_rows(kernel.size());
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = mask_box.y + j;
      const int* lab = label.ptr<int>(y);
      auto* dst = color.ptr<cv::Vec3f>(y);
      const bool rows_inside = y - reach_y >= 0 && y + reach_y < H;
      for (size_t k = 0; k < kernel.size(); ++k) {
        const int yy = y + kernel[k].dy;
        const bool valid = yy >= 0 && yy < H;
        prefix_rows[k] = valid && !src.prefix.empty() ? src.prefix_row(yy) : nullptr;
        rgb_rows[k] = valid ? src.rgb_row(yy) : nullptr;
      }
      // Near the border: taps outside the frame are dropped and the rest renormalised.
      auto border_pixel = [&](int x) {
        f4 sum{0, 0, 0, 0};
        float weight = 0;
        for (const Run& run : runs) {
          if (!rgb_rows[run.row]) continue;
          const int lo = std::max(x + run.lo, 0), hi = std::min(x + run.hi, W);
          if (lo < hi) {
            sum += prefix_rows[run.row][hi] - prefix_rows[run.row][lo];
            weight += static_cast<float>(hi - lo);
          }
        }
        for (const Tap& tap : taps) {
          const int xx = x + tap.dx;
          if (!rgb_rows[tap.row] || xx < 0 || xx >= W) continue;
          sum += tap.w * rgb_rows[tap.row][xx];
          weight += tap.w;
        }
        sum = weight > 0 ? sum * (1.0f / weight) : src.rgb_row(y)[x];
        dst[x] = cv::Vec3f(sum[0], sum[1], sum[2]);
      };
      // The fast path needs the whole kernel inside the frame: rows, and columns
      // [reach_x, W - reach_x).
      const int fast_lo = rows_inside ? reach_x : W, fast_hi = rows_inside ? W - reach_x : W;
      const RowKernel row_kernel{runs, taps, prefix_rows.data(), rgb_rows.data(), inv_total};
      // Blurs the drop pixels of columns [from, to): each run of them at once.
      auto blur_columns = [&](int from, int to) {
        for (int x = from; x < to;) {
          while (x < to && lab[x] < 0) ++x;
          int b = x;  // [x, b): a run of drop pixels
          while (b < to && lab[b] >= 0) ++b;
          if (b == x) break;
          const int a_fast = std::min(std::max(x, fast_lo), b), b_fast = std::max(std::min(b, fast_hi), a_fast);
          for (int i = x; i < a_fast; ++i) border_pixel(i);
          int i = blur_span_wide(level, row_kernel, a_fast, b_fast, dst);
          for (; i + kBlock <= b_fast; i += kBlock) sum_wide<f4, kBlock>(row_kernel, i, dst);
          for (; i < b_fast; ++i) sum_wide<f4, 1>(row_kernel, i, dst);
          for (i = b_fast; i < b; ++i) border_pixel(i);
          x = b;
        }
      };
      // Only the tracer's spans hold drop pixels: the rest of the mask box's row is not scanned.
      const int begin = mask_box.x, end = mask_box.x + mask_box.width;
      if (!spans) {
        blur_columns(begin, end);
        continue;
      }
      for (const auto& [a, e] : (*spans)[y]) blur_columns(std::max(a, begin), std::min(e + 1, end));
    }
  });
}

void blur_gaussian(const Source& src, const cv::Mat& label, cv::Mat& color, const cv::Rect& mask_box,
                   double diameter) {
  const double sigma = std::max(diameter / 4.0, 1e-6);
  const int R = static_cast<int>(std::ceil(3 * sigma));
  std::vector<float> g(2 * R + 1);
  for (int i = -R; i <= R; ++i) g[i + R] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  // Horizontal pass over every source row (its weight in the pad lane, for renormalising at
  // the frame border), vertical pass at drop pixels only.
  F4Buffer horiz(static_cast<size_t>(src.w) * src.h);
  tbb::parallel_for(tbb::blocked_range<int>(0, src.h, 8), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const f4* s = src.rgb.data() + static_cast<size_t>(j) * src.w - src.x0;
      f4* h = horiz.data() + static_cast<size_t>(j) * src.w - src.x0;
      for (const auto& [a, b] : src.intervals[j]) {
        for (int x = a; x <= b; ++x) {
          f4 sum{0, 0, 0, 0};
          for (int k = std::max(-R, a - x); k <= std::min(R, b - x); ++k) {
            sum += g[k + R] * s[x + k];
            sum[3] += g[k + R];
          }
          h[x] = sum;
        }
      }
    }
  });
  F4Buffer out(static_cast<size_t>(mask_box.width) * mask_box.height);
  tbb::parallel_for(tbb::blocked_range<int>(0, mask_box.height, 4), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = mask_box.y + j;
      const int* lab = label.ptr<int>(y);
      f4* dst = out.data() + static_cast<size_t>(j) * mask_box.width;
      for (int i = 0; i < mask_box.width; ++i) {
        const int x = mask_box.x + i;
        if (lab[x] < 0) continue;
        f4 sum{0, 0, 0, 0};
        float wsum = 0;
        for (int k = -R; k <= R; ++k) {
          const int sy = y + k - src.y0;
          if (sy < 0 || sy >= src.h) continue;
          const f4 h = horiz[static_cast<size_t>(sy) * src.w + (x - src.x0)];
          sum += g[k + R] * h;
          wsum += g[k + R] * h[3];
        }
        dst[i] = sum * (1.0f / wsum);
      }
    }
  });
  store(out, label, color, mask_box);
}

int kernel_reach(double diameter, BlurMethod method) {
  if (method == BlurMethod::Gaussian) return static_cast<int>(std::ceil(3 * std::max(diameter / 4.0, 1e-6)));
  return static_cast<int>(std::ceil(0.5 * diameter + 0.5));
}

}  // namespace

int blur_simd_level() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const int level = __builtin_cpu_supports("avx512f") ? 2 : __builtin_cpu_supports("avx") ? 1 : 0;
  return level;
#else
  return 0;
#endif
}

void force_blur_simd_level(int level) { forced_simd_level.store(level, std::memory_order_relaxed); }

int blur_simd_level_used() { return simd_level(); }

void blur_drops(const cv::Mat& clean, const cv::Mat& label, cv::Mat& color, double diameter_px,
                BlurMethod method, const cv::Rect* drop_box, const Spans* spans) {
  if (!(diameter_px > 0)) return;
  // Bounding box of the mask, then of everything the kernel reads.
  const cv::Rect mask_box = drop_box ? *drop_box : cv::boundingRect(cv::Mat(label >= 0));
  if (mask_box.empty()) return;
  const int reach = kernel_reach(diameter_px, method);
  const cv::Rect read_box = cv::Rect(mask_box.x - reach, mask_box.y - reach, mask_box.width + 2 * reach,
                                     mask_box.height + 2 * reach) &
                            cv::Rect(0, 0, label.cols, label.rows);
  const bool runs = method == BlurMethod::DiskSpan || method == BlurMethod::DiskAntialiased;
  const Source src = make_source(clean, label, color, read_box, runs, spans, reach);
  if (method == BlurMethod::Gaussian) {
    blur_gaussian(src, label, color, mask_box, diameter_px);
    return;
  }
  const bool aa = method == BlurMethod::DiskAntialiased;
  blur_rows(src, label, color, mask_box, disk_rows(diameter_px, aa, runs), spans);
}

cv::Mat blur_kernel(double diameter_px, BlurMethod method) {
  const int R = kernel_reach(diameter_px, method);
  cv::Mat k(2 * R + 1, 2 * R + 1, CV_64F, cv::Scalar(0));
  if (method == BlurMethod::Gaussian) {
    const double sigma = std::max(diameter_px / 4.0, 1e-6);
    for (int y = -R; y <= R; ++y)
      for (int x = -R; x <= R; ++x) k.at<double>(y + R, x + R) = std::exp(-0.5 * (x * x + y * y) / (sigma * sigma));
  } else {
    for (const KernelRow& row : disk_rows(diameter_px, method == BlurMethod::DiskAntialiased, true)) {
      for (int x = row.run_lo; x <= row.run_hi; ++x) k.at<double>(row.dy + R, x + R) = 1.0;
      for (const auto& [dx, w] : row.taps) k.at<double>(row.dy + R, dx + R) = w;
    }
  }
  return k / cv::sum(k)[0];
}

}  // namespace raindrop
