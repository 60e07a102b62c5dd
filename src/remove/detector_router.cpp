#include "raindrop/remove/detector_router.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/key_file.h"

namespace raindrop::removal {
namespace fs = std::filesystem;
namespace {

constexpr int kSmallPart = 30;  // pixels

// How many 8-connected parts `binary` has of at most kSmallPart pixels, and their median area.
std::pair<double, double> parts(const cv::Mat& binary) {
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(binary, labels, stats, centroids, 8, CV_32S);
  std::vector<int> areas;
  for (int i = 1; i < n; ++i) areas.push_back(stats.at<int>(i, cv::CC_STAT_AREA));
  if (areas.empty()) return {0.0, 0.0};
  const double small = static_cast<double>(std::count_if(areas.begin(), areas.end(), [](int a) { return a <= kSmallPart; }));
  std::sort(areas.begin(), areas.end());
  const size_t m = areas.size() / 2;
  const double median = areas.size() % 2 ? areas[m] : 0.5 * (static_cast<double>(areas[m - 1]) + areas[m]);
  return {small, median};
}

}  // namespace

RouterFeatures router_features(const cv::Mat& prob) {
  CV_Assert(prob.type() == CV_32F && !prob.empty());
  const double n = static_cast<double>(prob.total());
  double above_03 = 0, between = 0, sum = 0, above_002 = 0;
  for (int y = 0; y < prob.rows; ++y) {
    const float* p = prob.ptr<float>(y);
    for (int x = 0; x < prob.cols; ++x) {
      const float v = p[x];
      above_03 += v > 0.3f;
      between += v > 0.05f && v <= 0.3f;
      above_002 += v > 0.02f;
      sum += v;
    }
  }
  std::vector<double> f = {above_03 / n, between / n, sum / n, above_002 / n};
  for (const float t : {0.05f, 0.15f, 0.3f}) {
    cv::Mat binary(prob.size(), CV_8U);
    for (int y = 0; y < prob.rows; ++y) {
      const float* p = prob.ptr<float>(y);
      unsigned char* b = binary.ptr<unsigned char>(y);
      for (int x = 0; x < prob.cols; ++x) b[x] = p[x] > t;
    }
    const auto [small, median] = parts(binary);
    f.push_back(small / n * 1e4);
    f.push_back(median);
  }
  RouterFeatures out{};
  for (int i = 0; i < kRouterFeatures; ++i) out[i] = std::log1p(f[i] * 100);
  return out;
}

double DetectorRouter::score(const RouterFeatures& f) const {
  double z = bias;
  for (int i = 0; i < kRouterFeatures; ++i) z += weight[i] * (f[i] - mean[i]) / std[i];
  return z;
}

std::optional<DetectorRouter> read_detector_router(const fs::path& model_dir) {
  const fs::path file = model_dir / "ROUTER";
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  const KeyFile kf = read_key_file(file, [file](const std::string& why) {
    return Error(quoted(file) + ": " + why + " (docs/CONTRACTS.md, \"Detector router\"; or run without it: --no-router)");
  });
  kf.expect_format("1");
  DetectorRouter r;
  r.alternative = kf.folder_name("alternative", "one sibling model folder");
  const auto fill = [&](const std::string& key, RouterFeatures& dst, bool positive = false) {
    const std::vector<double> v = kf.numbers(key, kRouterFeatures, positive);
    std::copy(v.begin(), v.end(), dst.begin());
  };
  fill("mean", r.mean);
  fill("std", r.std, /*positive=*/true);
  fill("weight", r.weight);
  r.bias = kf.numbers("bias", 1)[0];
  return r;
}

}  // namespace raindrop::removal
