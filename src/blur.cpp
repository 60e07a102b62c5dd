#include "raindrop/blur.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace raindrop {
namespace {

// Area of the unit pixel [x-0.5,x+0.5]x[y-0.5,y+0.5] inside the disk of radius r, by a
// 16x16 midpoint rule (exact for pixels entirely in or out; error < 1/256 of a pixel on the
// rim, far below 8-bit resolution after normalisation).
double pixel_area_in_disk(int x, int y, double r) {
  constexpr int kSub = 16;
  int inside = 0;
  for (int j = 0; j < kSub; ++j) {
    const double yy = y - 0.5 + (j + 0.5) / kSub;
    for (int i = 0; i < kSub; ++i) {
      const double xx = x - 0.5 + (i + 0.5) / kSub;
      inside += xx * xx + yy * yy <= r * r;
    }
  }
  return static_cast<double>(inside) / (kSub * kSub);
}

// A kernel row: pixels [run_lo, run_hi] have weight 1, `taps` are the others.
struct KernelRow {
  int dy = 0;
  int run_lo = 1, run_hi = 0;  // empty when run_lo > run_hi
  std::vector<std::pair<int, float>> taps;
};

std::vector<KernelRow> disk_rows(double diameter, bool antialiased, bool split_runs) {
  const double r = 0.5 * diameter;
  const int R = static_cast<int>(std::ceil(r + 0.5));
  std::vector<KernelRow> rows;
  if (r <= 0.5) {
    // The disk lies inside the centre pixel: the exact kernel is the identity (a midpoint
    // rule would miss a tiny disk entirely and leave no weight at all).
    KernelRow row;
    if (split_runs) {
      row.run_lo = row.run_hi = 0;
    } else {
      row.taps.push_back({0, 1.0f});
    }
    rows.push_back(row);
    return rows;
  }
  for (int dy = -R; dy <= R; ++dy) {
    KernelRow row;
    row.dy = dy;
    for (int dx = -R; dx <= R; ++dx) {
      const double w = antialiased ? pixel_area_in_disk(dx, dy, r) : (dx * dx + dy * dy <= r * r ? 1.0 : 0.0);
      if (w <= 0) continue;
      if (split_runs && w >= 1.0 && (row.run_lo > row.run_hi || dx == row.run_hi + 1)) {
        if (row.run_lo > row.run_hi) row.run_lo = dx;
        row.run_hi = dx;
      } else {
        row.taps.push_back({dx, static_cast<float>(w)});
      }
    }
    if (row.run_lo <= row.run_hi || !row.taps.empty()) rows.push_back(std::move(row));
  }
  return rows;
}

// Rows [y0, y1] x cols [x0, x1] of the source the blur reads: the traced colour inside
// drops, the clean pixel outside.
struct Source {
  int x0, y0, w, h;
  cv::Mat rgb;     // CV_32FC3, h x w
  cv::Mat prefix;  // CV_32FC3, h x (w + 1): prefix[y][x] = sum of rgb[y][0..x-1]
};

Source make_source(const cv::Mat& clean, const cv::Mat& label, const cv::Mat& color,
                   const cv::Rect& box, bool prefix) {
  Source s{box.x, box.y, box.width, box.height, cv::Mat(box.height, box.width, CV_32FC3), {}};
  if (prefix) s.prefix = cv::Mat(box.height, box.width + 1, CV_32FC3);
  tbb::parallel_for(tbb::blocked_range<int>(0, box.height, 16), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = box.y + j;
      const auto* c8 = clean.ptr<cv::Vec3b>(y) + box.x;
      const int* lab = label.ptr<int>(y) + box.x;
      const auto* col = color.ptr<cv::Vec3f>(y) + box.x;
      auto* dst = s.rgb.ptr<cv::Vec3f>(j);
      for (int i = 0; i < box.width; ++i) {
        dst[i] = lab[i] >= 0 ? col[i] : cv::Vec3f(c8[i][0], c8[i][1], c8[i][2]) * (1.0f / 255.0f);
      }
      if (prefix) {
        auto* p = s.prefix.ptr<cv::Vec3f>(j);
        p[0] = cv::Vec3f(0, 0, 0);
        for (int i = 0; i < box.width; ++i) p[i + 1] = p[i] + dst[i];
      }
    }
  });
  return s;
}

void blur_rows(const Source& src, const cv::Mat& label, cv::Mat& color, const cv::Rect& mask_box,
               const std::vector<KernelRow>& kernel) {
  const int W = label.cols, H = label.rows;
  cv::Mat out(mask_box.height, mask_box.width, CV_32FC3);
  tbb::parallel_for(tbb::blocked_range<int>(0, mask_box.height, 4), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = mask_box.y + j;
      const int* lab = label.ptr<int>(y);
      auto* dst = out.ptr<cv::Vec3f>(j);
      for (int i = 0; i < mask_box.width; ++i) {
        const int x = mask_box.x + i;
        if (lab[x] < 0) continue;
        cv::Vec3f sum(0, 0, 0);
        float weight = 0;
        for (const KernelRow& row : kernel) {
          const int yy = y + row.dy;
          if (yy < 0 || yy >= H) continue;  // outside the frame: renormalised below
          const int sy = yy - src.y0;
          if (row.run_lo <= row.run_hi) {
            const int lo = std::max(x + row.run_lo, 0), hi = std::min(x + row.run_hi, W - 1);
            if (lo <= hi) {
              const auto* p = src.prefix.ptr<cv::Vec3f>(sy);
              sum += p[hi - src.x0 + 1] - p[lo - src.x0];
              weight += static_cast<float>(hi - lo + 1);
            }
          }
          const auto* s = src.rgb.ptr<cv::Vec3f>(sy);
          for (const auto& [dx, w] : row.taps) {
            const int xx = x + dx;
            if (xx < 0 || xx >= W) continue;
            sum += w * s[xx - src.x0];
            weight += w;
          }
        }
        dst[i] = weight > 0 ? sum * (1.0f / weight) : src.rgb.at<cv::Vec3f>(y - src.y0, x - src.x0);
      }
    }
  });
  for (int j = 0; j < mask_box.height; ++j) {
    const int y = mask_box.y + j;
    const int* lab = label.ptr<int>(y);
    const auto* o = out.ptr<cv::Vec3f>(j);
    auto* c = color.ptr<cv::Vec3f>(y);
    for (int i = 0; i < mask_box.width; ++i) {
      if (lab[mask_box.x + i] >= 0) c[mask_box.x + i] = o[i];
    }
  }
}

void blur_gaussian(const Source& src, const cv::Mat& label, cv::Mat& color, const cv::Rect& mask_box,
                   double diameter) {
  const double sigma = std::max(diameter / 4.0, 1e-6);
  const int R = static_cast<int>(std::ceil(3 * sigma));
  std::vector<float> g(2 * R + 1);
  for (int i = -R; i <= R; ++i) g[i + R] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  const int W = label.cols;
  // Horizontal pass over every source row, vertical pass at mask pixels only.
  cv::Mat horiz(src.h, src.w, CV_32FC3), hweight(src.h, src.w, CV_32F);
  tbb::parallel_for(tbb::blocked_range<int>(0, src.h, 8), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const auto* s = src.rgb.ptr<cv::Vec3f>(j);
      auto* h = horiz.ptr<cv::Vec3f>(j);
      auto* hw = hweight.ptr<float>(j);
      for (int i = 0; i < src.w; ++i) {
        const int x = src.x0 + i;
        cv::Vec3f sum(0, 0, 0);
        float wsum = 0;
        for (int k = -R; k <= R; ++k) {
          const int xx = x + k;
          if (xx < 0 || xx >= W || xx < src.x0 || xx >= src.x0 + src.w) continue;
          sum += g[k + R] * s[xx - src.x0];
          wsum += g[k + R];
        }
        h[i] = sum;
        hw[i] = wsum;
      }
    }
  });
  cv::Mat out(mask_box.height, mask_box.width, CV_32FC3);
  tbb::parallel_for(tbb::blocked_range<int>(0, mask_box.height, 4), [&](const tbb::blocked_range<int>& r) {
    for (int j = r.begin(); j < r.end(); ++j) {
      const int y = mask_box.y + j;
      const int* lab = label.ptr<int>(y);
      auto* dst = out.ptr<cv::Vec3f>(j);
      for (int i = 0; i < mask_box.width; ++i) {
        const int x = mask_box.x + i;
        if (lab[x] < 0) continue;
        cv::Vec3f sum(0, 0, 0);
        float wsum = 0;
        for (int k = -R; k <= R; ++k) {
          const int sy = y + k - src.y0;
          if (sy < 0 || sy >= src.h) continue;
          sum += g[k + R] * horiz.at<cv::Vec3f>(sy, x - src.x0);
          wsum += g[k + R] * hweight.at<float>(sy, x - src.x0);
        }
        dst[i] = sum * (1.0f / wsum);
      }
    }
  });
  for (int j = 0; j < mask_box.height; ++j) {
    const int y = mask_box.y + j;
    const int* lab = label.ptr<int>(y);
    for (int i = 0; i < mask_box.width; ++i) {
      if (lab[mask_box.x + i] >= 0) color.at<cv::Vec3f>(y, mask_box.x + i) = out.at<cv::Vec3f>(j, i);
    }
  }
}

int kernel_reach(double diameter, BlurMethod method) {
  if (method == BlurMethod::Gaussian) return static_cast<int>(std::ceil(3 * std::max(diameter / 4.0, 1e-6)));
  return static_cast<int>(std::ceil(0.5 * diameter + 0.5));
}

}  // namespace

void blur_drops(const cv::Mat& clean, const cv::Mat& label, cv::Mat& color, double diameter_px,
                BlurMethod method) {
  if (!(diameter_px > 0)) return;
  // Bounding box of the mask, then of everything the kernel reads.
  cv::Mat nonzero = label >= 0;
  const cv::Rect mask_box = cv::boundingRect(nonzero);
  if (mask_box.empty()) return;
  const int reach = kernel_reach(diameter_px, method);
  const cv::Rect read_box = cv::Rect(mask_box.x - reach, mask_box.y - reach, mask_box.width + 2 * reach,
                                     mask_box.height + 2 * reach) &
                            cv::Rect(0, 0, label.cols, label.rows);
  const bool runs = method == BlurMethod::DiskSpan || method == BlurMethod::DiskAntialiased;
  const Source src = make_source(clean, label, color, read_box, runs);
  if (method == BlurMethod::Gaussian) {
    blur_gaussian(src, label, color, mask_box, diameter_px);
    return;
  }
  const bool aa = method == BlurMethod::DiskAntialiased;
  blur_rows(src, label, color, mask_box, disk_rows(diameter_px, aa, runs));
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
