#include "raindrop/remove/large_drops.h"

#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "raindrop/remove/pixels.h"

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
