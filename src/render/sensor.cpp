#include "raindrop/render/sensor.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "raindrop/common/image_io.h"

namespace raindrop {
namespace {

// Streams of their own, apart from the scene's (sample_scene draws from the sample seed itself).
constexpr std::uint64_t kDrawStream = hash_string("sensor: draw");
constexpr std::uint64_t kNoiseStream = hash_string("sensor: noise");

// Standard normal quantiles at (i + 0.5) / 65536: a Gaussian draw is then one table lookup per
// 16 random bits (four per 64-bit draw), about five times faster than Box-Muller's log, sqrt
// and cos per pair (docs/RESULTS.md 4.9), and still exact to rounding where it matters (noise is rounded to whole levels;
// the table's tails end at 4.3 sigma, leaving out 2e-5 of the mass).
const std::vector<float>& normal_quantiles() {
  static const std::vector<float> table = [] {
    std::vector<float> t(1 << 16);
    for (size_t i = 0; i < t.size(); ++i) {
      const double p = (static_cast<double>(i) + 0.5) / static_cast<double>(t.size());
      // Phi(z) = p by bisection (Phi is monotonic; 40 halvings of [-9, 9] leave 2e-11).
      double lo = -9, hi = 9;
      for (int k = 0; k < 40; ++k) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
      }
      const double z = 0.5 * (lo + hi);
      t[i] = static_cast<float>(z);
    }
    return t;
  }();
  return table;
}

}  // namespace

SensorSample sample_sensor(const SceneConfig& config, std::uint64_t sample_seed) {
  SensorSample s;
  if (!config.sensor.enabled) return s;
  Rng rng(mix64(sample_seed ^ kDrawStream));
  s.noise_sigma = rng.uniform(config.sensor.noise_levels.lo, config.sensor.noise_levels.hi);
  if (config.sensor.jpeg_quality.hi > 0) {
    s.jpeg_quality = rng.uniform_int(static_cast<int>(config.sensor.jpeg_quality.lo),
                                     static_cast<int>(config.sensor.jpeg_quality.hi));
  }
  return s;
}

void apply_sensor(cv::Mat& rgb, const SensorSample& sensor, std::uint64_t sample_seed) {
  CV_Assert(rgb.type() == CV_8UC3);
  if (sensor.noise_sigma > 0) {
    // One stream per row, so the field does not depend on how rows are split among threads
    // (rows run in order here; the per-row seed keeps that a free choice).
    const std::vector<float>& quantile = normal_quantiles();
    const float sigma = static_cast<float>(sensor.noise_sigma);
    for (int y = 0; y < rgb.rows; ++y) {
      Rng rng(mix64(sample_seed ^ kNoiseStream) + static_cast<std::uint64_t>(y));
      auto* p = rgb.ptr<unsigned char>(y);
      const int n = 3 * rgb.cols;
      for (int i = 0; i < n; i += 4) {
        std::uint64_t bits = rng.next_u64();
        for (int k = 0; k < 4 && i + k < n; ++k, bits >>= 16) {
          const float v = static_cast<float>(p[i + k]) + sigma * quantile[bits & 0xffff];
          p[i + k] = static_cast<unsigned char>(std::clamp(std::lround(v), 0L, 255L));
        }
      }
    }
  }
  if (sensor.jpeg_quality > 0) rgb = jpeg_round_trip(rgb, sensor.jpeg_quality);
}

}  // namespace raindrop
