#include "raindrop/remove/surround_fill.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "raindrop/remove/pixels.h"
#include "raindrop/remove/working_scale.h"

namespace raindrop::removal {
namespace {

// One level of the pyramid: premultiplied colour N (3 planes) and weight W, h x w.
struct Level {
  int h = 0, w = 0;
  std::vector<float> n, wt;
};

Level push(const Level& f) {
  Level c;
  c.h = (f.h + 1) / 2;
  c.w = (f.w + 1) / 2;
  const size_t fp = static_cast<size_t>(f.h) * f.w, cp = static_cast<size_t>(c.h) * c.w;
  c.n.assign(3 * cp, 0.0f);
  c.wt.assign(cp, 0.0f);
  for (int y = 0; y < c.h; ++y) {
    const int ya = 2 * y, yb = std::min(2 * y + 1, f.h - 1);
    for (int x = 0; x < c.w; ++x) {
      const int xa = 2 * x, xb = std::min(2 * x + 1, f.w - 1);
      // The block's pixels that exist: 1, 2 or 4 (a repeated index is counted once).
      const int ys[2] = {ya, yb}, xs[2] = {xa, xb};
      const int ny = yb != ya ? 2 : 1, nx = xb != xa ? 2 : 1;
      const float inv = 1.0f / static_cast<float>(ny * nx);
      float sw = 0.0f, s[3] = {0.0f, 0.0f, 0.0f};
      for (int i = 0; i < ny; ++i) {
        for (int j = 0; j < nx; ++j) {
          const size_t p = static_cast<size_t>(ys[i]) * f.w + xs[j];
          sw += f.wt[p];
          for (int ch = 0; ch < 3; ++ch) s[ch] += f.n[ch * fp + p];
        }
      }
      const size_t q = static_cast<size_t>(y) * c.w + x;
      c.wt[q] = sw * inv;
      for (int ch = 0; ch < 3; ++ch) c.n[ch * cp + q] = s[ch] * inv;
    }
  }
  return c;
}

// Bilinear sample positions of fine index i (0..fine-1) on a coarse axis of `coarse` pixels:
// (i + 0.5) / 2 - 0.5, clamped to [0, coarse - 1].
struct Tap {
  int i0, i1;
  float t;
};
std::vector<Tap> taps(int fine, int coarse) {
  std::vector<Tap> out(fine);
  for (int i = 0; i < fine; ++i) {
    const float pos = std::clamp((static_cast<float>(i) + 0.5f) * 0.5f - 0.5f, 0.0f, static_cast<float>(coarse - 1));
    const int i0 = static_cast<int>(pos);
    out[i] = {i0, std::min(i0 + 1, coarse - 1), pos - static_cast<float>(i0)};
  }
  return out;
}

// The parts of `mask` chosen by the rule of surround_fill.h: their labels in `labels` (CV_32S,
// 8-connected parts of `mask`) and their bounding boxes.
struct ChosenParts {
  cv::Mat labels;
  std::vector<int> ids;
  std::vector<cv::Rect> boxes;
  std::vector<float> medians;  // each part's surround median luma (8-bit levels)
};

ChosenParts choose_parts(const cv::Mat& mask, const float* rgb, int max_area, double max_mad) {
  CV_Assert(mask.type() == CV_8UC1);
  ChosenParts out;
  if (max_area <= 0) return out;
  const int h = mask.rows, w = mask.cols;
  const size_t plane = static_cast<size_t>(h) * w;
  cv::Mat stats, centroids;
  const int parts = cv::connectedComponentsWithStats(mask, out.labels, stats, centroids, 8, CV_32S);
  std::vector<float> ring;
  for (int k = 1; k < parts; ++k) {
    if (stats.at<int>(k, cv::CC_STAT_AREA) > max_area) continue;
    const cv::Rect box(stats.at<int>(k, cv::CC_STAT_LEFT), stats.at<int>(k, cv::CC_STAT_TOP),
                       stats.at<int>(k, cv::CC_STAT_WIDTH), stats.at<int>(k, cv::CC_STAT_HEIGHT));
    const int x0 = std::max(0, box.x - kSurroundRing), y0 = std::max(0, box.y - kSurroundRing);
    const int x1 = std::min(w, box.x + box.width + kSurroundRing), y1 = std::min(h, box.y + box.height + kSurroundRing);
    ring.clear();
    for (int y = y0; y < y1; ++y) {
      const unsigned char* m = mask.ptr<unsigned char>(y);
      for (int x = x0; x < x1; ++x) {
        if (m[x]) continue;
        const size_t p = static_cast<size_t>(y) * w + x;
        ring.push_back(255.0f * luma(rgb[p], rgb[plane + p], rgb[2 * plane + p]));
      }
    }
    if (ring.size() < 4) continue;
    const auto mid = ring.begin() + static_cast<std::ptrdiff_t>(ring.size() / 2);
    std::nth_element(ring.begin(), mid, ring.end());
    const float median = *mid;
    for (float& value : ring) value = std::abs(value - median);
    std::nth_element(ring.begin(), mid, ring.end());
    if (*mid <= max_mad) {
      out.ids.push_back(k);
      out.boxes.push_back(box);
      out.medians.push_back(median);
    }
  }
  return out;
}

// Grows each chosen part into its rim (surround_fill.h, grow_into_rims): step by step, the
// 8-neighbours outside `mask` whose luma lies more than kRimLevels from the part's surround
// median, at most `rim` steps; kept only where that structure ends there (the next step would
// add at most kRimContinuation times what the last one took: a ring thins out to nothing, a
// pole or an edge adds as much at every step). The pixels taken join the part's label
// and `mask`. Parts are grown in turn, so a pixel between two goes to the first.
void grow_into_rims(ChosenParts& chosen, const float* rgb, cv::Mat& mask, int rim) {
  if (rim <= 0 || chosen.ids.empty()) return;
  const int h = mask.rows, w = mask.cols;
  const size_t plane = static_cast<size_t>(h) * w;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  for (size_t i = 0; i < chosen.ids.size(); ++i) {
    const cv::Rect box = chosen.boxes[i];
    const int reach = rim + 2;
    const cv::Rect win = cv::Rect(box.x - reach, box.y - reach, box.width + 2 * reach, box.height + 2 * reach) &
                         cv::Rect(0, 0, w, h);
    // Pixels of the window that may be taken: outside the mask, and off the part's surround
    // median by more than kRimLevels.
    cv::Mat off(win.size(), CV_8U, cv::Scalar(0));
    for (int y = 0; y < win.height; ++y) {
      const unsigned char* m = mask.ptr<unsigned char>(win.y + y) + win.x;
      unsigned char* o = off.ptr<unsigned char>(y);
      for (int x = 0; x < win.width; ++x) {
        if (m[x]) continue;
        const size_t p = static_cast<size_t>(win.y + y) * w + win.x + x;
        o[x] = std::abs(255.0f * luma(rgb[p], rgb[plane + p], rgb[2 * plane + p]) - chosen.medians[i]) > kRimLevels;
      }
    }
    cv::Mat grown = chosen.labels(win) == chosen.ids[i];  // 0/255
    cv::Mat taken(win.size(), CV_8U, cv::Scalar(0)), ring;
    int last = 0, next = 0;  // the pixels the last step took, and those the next one would
    for (int step = 0; step <= rim; ++step) {
      cv::dilate(grown, ring, kernel);
      ring &= off;
      ring.setTo(0, taken);
      const int n = cv::countNonZero(ring);
      if (step == rim || n == 0) {
        next = n;
        break;
      }
      taken |= ring;
      grown |= ring;
      last = n;
    }
    if (last == 0 || next > kRimContinuation * last) continue;  // no rim, or scenery that goes on
    cv::Rect taken_box = cv::boundingRect(taken);
    taken_box.x += win.x;
    taken_box.y += win.y;
    // A band that reaches the edge of the mask given (the image's, or a tile's window) may go on
    // past it: it cannot be told from a rim, so it is left alone.
    if (taken_box.x == 0 || taken_box.y == 0 || taken_box.br().x == w || taken_box.br().y == h) continue;
    chosen.labels(win).setTo(chosen.ids[i], taken);
    mask(win).setTo(1, taken);
    chosen.boxes[i] = box | taken_box;
  }
}

// The chosen parts as one CV_8U 0/255 mask.
cv::Mat chosen_mask(const ChosenParts& chosen, cv::Size size) {
  cv::Mat out(size, CV_8U, cv::Scalar(0));
  for (size_t i = 0; i < chosen.ids.size(); ++i) {
    const cv::Rect& box = chosen.boxes[i];
    out(box).setTo(255, chosen.labels(box) == chosen.ids[i]);
  }
  return out;
}

}  // namespace

bool push_pull_fill(const float* rgb, int h, int w, const cv::Mat& hole, float* out) {
  CV_Assert(hole.type() == CV_8UC1 && hole.rows == h && hole.cols == w);
  const size_t plane = static_cast<size_t>(h) * w;
  std::vector<Level> levels(1);
  Level& l0 = levels[0];
  l0.h = h;
  l0.w = w;
  l0.n.resize(3 * plane);
  l0.wt.resize(plane);
  bool any_known = false;
  for (int y = 0; y < h; ++y) {
    const unsigned char* m = hole.ptr<unsigned char>(y);
    for (int x = 0; x < w; ++x) {
      const size_t p = static_cast<size_t>(y) * w + x;
      const float known = m[x] ? 0.0f : 1.0f;
      any_known = any_known || known > 0.0f;
      l0.wt[p] = known;
      for (int ch = 0; ch < 3; ++ch) l0.n[ch * plane + p] = known * rgb[ch * plane + p];
    }
  }
  if (!any_known) return false;
  while (levels.back().h > 1 || levels.back().w > 1) levels.push_back(push(levels.back()));

  // Pull: V at the coarsest level, then V = N + (1 - W) * upsampled V at each finer one.
  std::vector<float> v;
  {
    const Level& top = levels.back();
    const size_t tp = static_cast<size_t>(top.h) * top.w;
    v.resize(3 * tp);
    for (size_t p = 0; p < tp; ++p)
      for (int ch = 0; ch < 3; ++ch) v[ch * tp + p] = top.wt[p] > 0.0f ? top.n[ch * tp + p] / top.wt[p] : 0.0f;
  }
  for (int l = static_cast<int>(levels.size()) - 2; l >= 0; --l) {
    const Level& f = levels[l];
    const Level& c = levels[l + 1];
    const size_t fp = static_cast<size_t>(f.h) * f.w, cp = static_cast<size_t>(c.h) * c.w;
    const std::vector<Tap> ty = taps(f.h, c.h), tx = taps(f.w, c.w);
    std::vector<float> next(3 * fp);
    for (int y = 0; y < f.h; ++y) {
      const Tap a = ty[y];
      for (int x = 0; x < f.w; ++x) {
        const Tap b = tx[x];
        const size_t p = static_cast<size_t>(y) * f.w + x;
        const float keep = 1.0f - f.wt[p];
        for (int ch = 0; ch < 3; ++ch) {
          const float* vc = v.data() + ch * cp;
          const float top = vc[static_cast<size_t>(a.i0) * c.w + b.i0] * (1.0f - b.t) +
                            vc[static_cast<size_t>(a.i0) * c.w + b.i1] * b.t;
          const float bottom = vc[static_cast<size_t>(a.i1) * c.w + b.i0] * (1.0f - b.t) +
                               vc[static_cast<size_t>(a.i1) * c.w + b.i1] * b.t;
          const float u = top * (1.0f - a.t) + bottom * a.t;
          next[ch * fp + p] = f.n[ch * fp + p] + keep * u;
        }
      }
    }
    v.swap(next);
  }
  // Outside the hole the input exactly (N + 0 * U is the input there up to the sum's rounding).
  for (int y = 0; y < h; ++y) {
    const unsigned char* m = hole.ptr<unsigned char>(y);
    for (int x = 0; x < w; ++x) {
      const size_t p = static_cast<size_t>(y) * w + x;
      for (int ch = 0; ch < 3; ++ch) out[ch * plane + p] = m[x] ? v[ch * plane + p] : rgb[ch * plane + p];
    }
  }
  return true;
}

cv::Mat surround_fill_mask(const cv::Mat& mask, const float* rgb, int max_area, double max_mad, int* filled_parts) {
  const ChosenParts chosen = choose_parts(mask, rgb, max_area, max_mad);
  if (filled_parts) *filled_parts = static_cast<int>(chosen.ids.size());
  return chosen_mask(chosen, mask.size());
}

int fill_small_drops_from_surround(const float* rgb, cv::Mat& mask, int max_area, double max_mad,
                                   std::vector<float>& ihat, cv::Mat* filled_parts, int rim) {
  const int h = mask.rows, w = mask.cols;
  const size_t plane = static_cast<size_t>(h) * w;
  CV_Assert(ihat.size() == 3 * plane);
  ChosenParts chosen = choose_parts(mask, rgb, max_area, max_mad);
  if (rim > 0) grow_into_rims(chosen, rgb, mask, rim);  // the caller's mask grows with the parts
  if (filled_parts) *filled_parts = chosen_mask(chosen, mask.size());
  if (chosen.ids.empty()) return 0;
  // Each part is filled from a window around it (its box grown by kSurroundWindow times its
  // larger side, at least 2 kSurroundRing): a drop is predicted by its neighbourhood, and the
  // cost follows the parts' size, not the image's. Every part of the mask is a hole there: the
  // other drops are no better a guess than the 3RN's.
  std::vector<cv::Rect> windows;
  double window_pixels = 0;
  for (const cv::Rect& box : chosen.boxes) {
    const int grow = std::max(2 * kSurroundRing, kSurroundWindow * std::max(box.width, box.height));
    windows.push_back(cv::Rect(box.x - grow, box.y - grow, box.width + 2 * grow, box.height + 2 * grow) &
                      cv::Rect(0, 0, w, h));
    window_pixels += static_cast<double>(windows.back().width) * windows.back().height;
  }
  // Thin or diagonal parts have large windows for their area; past kSurroundWindowBudget times
  // the image, one fill of the whole image is cheaper than theirs and bounds the cost.
  if (window_pixels > kSurroundWindowBudget * static_cast<double>(plane)) windows.assign(chosen.ids.size(), cv::Rect(0, 0, w, h));
  std::vector<float> window_rgb, window_fill;
  cv::Rect filled;  // the window window_fill holds (several parts share the whole image's)
  for (size_t i = 0; i < chosen.ids.size(); ++i) {
    const cv::Rect& box = chosen.boxes[i];
    const cv::Rect& win = windows[i];
    const size_t wp = static_cast<size_t>(win.width) * static_cast<size_t>(win.height);
    if (win != filled) {
      window_rgb.resize(3 * wp);
      window_fill.resize(3 * wp);
      for (int ch = 0; ch < 3; ++ch)
        for (int y = 0; y < win.height; ++y)
          std::copy_n(rgb + ch * plane + static_cast<size_t>(win.y + y) * w + win.x, win.width,
                      window_rgb.data() + ch * wp + static_cast<size_t>(y) * win.width);
      // A chosen part has known pixels within its window (its surround), so this never refuses.
      push_pull_fill(window_rgb.data(), win.height, win.width, mask(win), window_fill.data());
      filled = win;
    }
    for (int y = box.y; y < box.y + box.height; ++y) {
      const int* lab = chosen.labels.ptr<int>(y);
      for (int x = box.x; x < box.x + box.width; ++x) {
        if (lab[x] != chosen.ids[i]) continue;
        const size_t p = static_cast<size_t>(y) * w + x;
        const size_t q = static_cast<size_t>(y - win.y) * win.width + (x - win.x);
        for (int ch = 0; ch < 3; ++ch) ihat[ch * plane + p] = window_fill[ch * wp + q];
      }
    }
  }
  return static_cast<int>(chosen.ids.size());
}

int surround_fill_area_at_scale(int area, cv::Size image_size, double scale) {
  const double reference = auto_working_scale(image_size, kDefaultWorkingSize);
  if (area <= 0 || scale == reference) return area;
  const double r = scale / reference;
  // Halves round up as round() does; the 1e-9 keeps a half that floating point lands a hair
  // below (0.6 / 0.4 is 1.4999999999999998) from rounding down. Clamped before the conversion.
  const double limit = std::floor(area * r * r + 0.5 + 1e-9);
  return limit >= static_cast<double>(std::numeric_limits<int>::max()) ? std::numeric_limits<int>::max()
                                                                        : static_cast<int>(limit);
}

int surround_fill_rim_at_scale(int rim, cv::Size image_size, double scale) {
  const double reference = auto_working_scale(image_size, kDefaultWorkingSize);
  if (rim <= 0 || scale == reference) return rim;
  // Halves round up, with surround_fill_area_at_scale's guard (3 x 0.6 / 0.4 is 4.4999999999999991);
  // at least one step: a rim given stays on at any scale.
  return std::max(1, static_cast<int>(std::floor(rim * scale / reference + 0.5 + 1e-9)));
}

}  // namespace raindrop::removal
