#include "raindrop/renderer.h"

#include <chrono>
#include <cmath>

#include "raindrop/blur.h"
#include "raindrop/drop_accel.h"

namespace raindrop {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

double RenderedFrame::coverage() const {
  return mask.empty() ? 0.0 : static_cast<double>(stats.drop_pixels) / (mask.total());
}

RenderedFrame render_frame(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                           const SceneSample& scene) {
  RenderedFrame frame;
  auto t0 = std::chrono::steady_clock::now();
  std::vector<Drop> drops;
  drops.reserve(scene.drops.size());
  for (const DropShape& shape : scene.drops) drops.emplace_back(shape, scene.glass);
  DropAccel accel(drops, config.geometry);
  // Non-overlapping footprints mean non-overlapping caps (a cap never reaches past its
  // footprint for contact angles up to 90 degrees).
  accel.set_disjoint(!config.allow_overlap);
  frame.timings.accel_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  TraceResult traced = trace_drops(clean, camera, config, scene, accel);
  frame.timings.trace_ms = ms_since(t0);
  frame.stats = traced.stats;

  t0 = std::chrono::steady_clock::now();
  if (config.blur.enabled) {
    blur_drops(clean, traced.label, traced.color, scene.blur_diameter_px, config.blur.method, &traced.drop_box, &traced.spans);
  }
  frame.timings.blur_ms = ms_since(t0);

  // Only drop pixels are written: everywhere else the rainy image is the clean bytes.
  t0 = std::chrono::steady_clock::now();
  frame.rainy = clean.clone();
  frame.mask = cv::Mat(clean.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < clean.rows; ++y) {
    const int* label = traced.label.ptr<int>(y);
    const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
    auto* out = frame.rainy.ptr<cv::Vec3b>(y);
    auto* m = frame.mask.ptr<std::uint8_t>(y);
    for (const auto& [x0, x1] : traced.spans[y]) for (int x = x0; x <= x1; ++x) {
      if (label[x] < 0) continue;
      m[x] = 255;
      for (int c = 0; c < 3; ++c) {
        const float v = std::isfinite(rgb[x][c]) ? rgb[x][c] : 0.0f;
        out[x][c] = static_cast<std::uint8_t>(std::floor(std::min(std::max(v, 0.0f), 1.0f) * 255.0f + 0.5f));
      }
    }
  }
  frame.timings.compose_ms = ms_since(t0);
  return frame;
}

}  // namespace raindrop
