#include "raindrop/remove/large_drops.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "raindrop/remove/pixels.h"
#include "raindrop/remove/working_scale.h"

namespace raindrop::removal {

namespace {

// keep[label] for every pixel of a label image (CV_32S) made by connectedComponents.
cv::Mat kept_labels(const cv::Mat& labels, const std::vector<unsigned char>& keep) {
  cv::Mat out(labels.size(), CV_8U);
  for (int y = 0; y < labels.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    unsigned char* o = out.ptr<unsigned char>(y);
    for (int x = 0; x < labels.cols; ++x) o[x] = keep[l[x]];
  }
  return out;
}

}  // namespace

int detail_blur_reduction(double sigma) { return std::max(1, static_cast<int>(sigma / 4.0)); }

void add_input_detail(const cv::Mat& input, const cv::Mat& weight_small, double sigma, double gain, cv::Mat& result,
                      cv::Mat* result_rgb) {
  CV_Assert(result.size() == input.size() && result.type() == input.type() && weight_small.type() == CV_32FC1);
  if (!(gain > 0.0) || !(sigma > 0.0)) return;
  const cv::Size full = input.size();
  const cv::Rect whole(cv::Point(0, 0), full);
  const cv::Rect reach = upsampled_reach(weight_small, full, whole);
  if (reach.empty()) return;
  // The blur of the pixels in reach needs its kernel's reach around them (OpenCV's float kernel
  // spans about 4 sigma each side); the image's own border is replicated, as a whole-image blur's.
  const int pad = static_cast<int>(std::ceil(4.0 * sigma)) + 2;
  const cv::Rect around = cv::Rect(reach.x - pad, reach.y - pad, reach.width + 2 * pad, reach.height + 2 * pad) & whole;
  // hi: the input's high frequencies over `around` (float RGB).
  cv::Mat hi;
  const int f = detail_blur_reduction(sigma);
  if (f == 1) {
    const cv::Mat in = to_rgb_float(input, around);
    cv::Mat blurred;
    cv::GaussianBlur(in, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
    hi = in - blurred;
  } else {
    // A wide blur on a copy f times smaller, its high frequencies upsampled: a 10-megapixel
    // photograph's sigma of 23 pixels took 4.4 s at full size. The copy is area-averaged from
    // the input as stored, so the full-size pixels are never converted to float here.
    cv::Mat small_stored, blurred;
    cv::resize(input(around), small_stored, cv::Size((around.width + f - 1) / f, (around.height + f - 1) / f), 0, 0,
               cv::INTER_AREA);
    const cv::Mat small = to_rgb_float(small_stored, cv::Rect(cv::Point(0, 0), small_stored.size()));
    cv::GaussianBlur(small, blurred, cv::Size(0, 0), sigma / f, sigma / f, cv::BORDER_REPLICATE);
    cv::resize(cv::Mat(small - blurred), hi, around.size(), 0, 0, cv::INTER_LINEAR);
  }
  const cv::Rect inner = reach - around.tl();
  const cv::Mat alpha = upsample_region(weight_small, full, reach);
  const float g = static_cast<float>(gain);
  const size_t pixel_bytes = result.elemSize();
  // Row by row on OpenCV's threads: each row through float where the weight is above 0, and
  // written back only there (elsewhere the result's own bytes, with no round trip through float).
  cv::parallel_for_(cv::Range(0, reach.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* a = alpha.ptr<float>(y);
      const cv::Rect row(reach.x, reach.y + y, reach.width, 1);
      cv::Mat out = result_rgb && !result_rgb->empty() ? (*result_rgb)(row).clone() : to_rgb_float(result, row);
      const cv::Vec3f* h = hi.ptr<cv::Vec3f>(inner.y + y) + inner.x;
      cv::Vec3f* o = out.ptr<cv::Vec3f>(0);
      for (int x = 0; x < reach.width; ++x) {
        if (a[x] <= 0.0f) continue;
        for (int c = 0; c < 3; ++c) o[x][c] = clamp01(o[x][c] + g * a[x] * h[x][c]);
      }
      cv::Mat stored = result(row).clone();
      store_rgb_float(out, stored, cv::Point(0, 0));
      const unsigned char* src = stored.ptr<unsigned char>(0);
      unsigned char* dst = result.ptr<unsigned char>(reach.y + y) + reach.x * pixel_bytes;
      cv::Vec3f* r = result_rgb && !result_rgb->empty() ? result_rgb->ptr<cv::Vec3f>(reach.y + y) + reach.x : nullptr;
      for (int x = 0; x < reach.width; ++x) {
        if (a[x] <= 0.0f) continue;
        std::memcpy(dst + x * pixel_bytes, src + x * pixel_bytes, pixel_bytes);
        if (r) r[x] = o[x];
      }
    }
  });
}

bool coarse_pass_fits(cv::Size coarse) {
  return coarse.width >= 2 * kLargeDropDiameter && coarse.height >= 2 * kLargeDropDiameter;
}

cv::Mat large_drop_mask(const cv::Mat& mask, int* count) {
  CV_Assert(mask.type() == CV_8UC1);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask != 0, labels, stats, centroids, 8, CV_32S);
  const double min_area = M_PI * 0.25 * kLargeDropDiameter * kLargeDropDiameter;
  std::vector<unsigned char> keep(n, 0);
  int kept = 0;
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= min_area) {
      keep[i] = 255;
      ++kept;
    }
  }
  if (count) *count = kept;
  return kept_labels(labels, keep);
}

cv::Mat sharpness_map(const cv::Mat& image) {
  // In bands of rows, each read with one row of margin on either side, so that the memory beyond
  // the map stays a band's (at --scale 1 the working-scale image can be a whole photograph).
  constexpr int kBand = 64;
  cv::Mat out(image.size(), CV_32F);
  for (int y0 = 0; y0 < image.rows; y0 += kBand) {
    const int y1 = std::min(image.rows, y0 + kBand);
    const int top = std::max(0, y0 - 1), bottom = std::min(image.rows, y1 + 1);
    const cv::Mat rgb = to_rgb_float(image, cv::Rect(0, top, image.cols, bottom - top));
    cv::Mat levels(rgb.size(), CV_32F);  // luma in 8-bit levels
    for (int y = 0; y < rgb.rows; ++y) {
      const auto* p = rgb.ptr<cv::Vec3f>(y);
      float* l = levels.ptr<float>(y);
      for (int x = 0; x < rgb.cols; ++x) l[x] = 255.0f * luma(p[x][0], p[x][1], p[x][2]);
    }
    // The margin rows are the true neighbours; at the image's own top and bottom the replicated
    // border is the rule.
    cv::Mat lap;
    cv::Laplacian(levels, lap, CV_32F, 1, 1.0, 0.0, cv::BORDER_REPLICATE);
    for (int y = y0; y < y1; ++y) {
      const float* src = lap.ptr<float>(y - top);
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < image.cols; ++x) dst[x] = std::abs(src[x]);
    }
  }
  return out;
}

cv::Mat smooth_large_drops(const cv::Mat& large, const cv::Mat& sharpness, double max_sharpness, int* count) {
  CV_Assert(large.type() == CV_8UC1 && sharpness.type() == CV_32FC1);
  cv::Mat local;
  if (sharpness.size() == large.size())
    local = sharpness;
  else
    cv::resize(sharpness, local, large.size(), 0, 0, cv::INTER_AREA);
  cv::Mat labels;
  const int n = cv::connectedComponents(large != 0, labels, 8, CV_32S);
  std::vector<double> sum(n, 0.0);
  std::vector<int> area(n, 0);
  for (int y = 0; y < large.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    const float* s = local.ptr<float>(y);
    for (int x = 0; x < large.cols; ++x) sum[l[x]] += s[x], ++area[l[x]];
  }
  std::vector<unsigned char> keep(n, 0);
  int kept = 0;
  for (int i = 1; i < n; ++i) {
    if (sum[i] <= max_sharpness * area[i]) {
      keep[i] = 255;
      ++kept;
    }
  }
  if (count) *count = kept;
  return kept_labels(labels, keep);
}

namespace {

// Planar channels mirrored left to right.
std::vector<float> mirrored(const float* planes, int channels, int h, int w) {
  std::vector<float> out(static_cast<size_t>(channels) * h * w);
  for (size_t row = 0; row < static_cast<size_t>(channels) * h; ++row) {
    const float* src = planes + row * w;
    float* dst = out.data() + row * w;
    for (int x = 0; x < w; ++x) dst[x] = src[w - 1 - x];
  }
  return out;
}

}  // namespace

void run_mirror_averaged(Network& net, const std::vector<const float*>& inputs, const std::vector<int>& channels, int h,
                         int w, int out_channels, float* output) {
  CV_Assert(inputs.size() == channels.size());
  std::vector<std::vector<float>> flipped;
  std::vector<const float*> flipped_inputs;
  flipped.reserve(inputs.size());
  for (size_t i = 0; i < inputs.size(); ++i) {
    flipped.push_back(mirrored(inputs[i], channels[i], h, w));
    flipped_inputs.push_back(flipped.back().data());
  }
  const size_t size = static_cast<size_t>(out_channels) * h * w;
  std::vector<float> direct(size), other(size);
  net.run(inputs, h, w, direct.data());
  net.run(flipped_inputs, h, w, other.data());
  const std::vector<float> back = mirrored(other.data(), out_channels, h, w);
  // (a + b) / 2 with the same operands in either view: the result is exactly mirror-equivariant.
  for (size_t i = 0; i < size; ++i) output[i] = 0.5f * (direct[i] + back[i]);
}

}  // namespace raindrop::removal
