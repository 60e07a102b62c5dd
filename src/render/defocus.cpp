#include "raindrop/render/defocus.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/render/blur.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/layer_mix.h"
#include "raindrop/render/srgb.h"

namespace raindrop {
namespace {

// Writes linear radiance where coverage > kNoCoverage (stored again through the highlights'
// inverse lift), the clean bytes elsewhere.
cv::Mat encode(const cv::Mat& clean, const cv::Mat& linear, const cv::Mat& coverage, const HighlightLift& lift) {
  cv::Mat rainy = clean.clone();
  const SrgbTables& srgb = SrgbTables::get();
  for (int y = 0; y < clean.rows; ++y) {
    const float* a = coverage.ptr<float>(y);
    const auto* rgb = linear.ptr<cv::Vec3f>(y);
    auto* out = rainy.ptr<cv::Vec3b>(y);
    for (int x = 0; x < clean.cols; ++x) {
      if (!(a[x] > kNoCoverage)) continue;
      float light[3] = {rgb[x][0], rgb[x][1], rgb[x][2]};
      lift.restore(light);
      for (int c = 0; c < 3; ++c) out[x][c] = srgb.encode(light[c]);
    }
  }
  return rainy;
}

}  // namespace

double layer_blur_diameter(const SceneSample& scene, const Drop& drop, double fx, cv::Size frame) {
  const double coc = scene.drop_coc_px(drop.shape(), fx);
  const double diameter = std::isfinite(coc) ? std::min(coc, 2.0 * std::max(frame.width, frame.height)) : 0.0;
  return diameter >= kMinVisibleCocPx ? diameter : 0.0;
}

double drop_lens_spread_px(const SceneSample& scene, const Drop& drop, double fx) {
  const double z = scene.glass.point(drop.shape().center).z;
  const double coc = scene.drop_coc_px(drop.shape(), fx);
  if (!(z > 0) || !std::isfinite(coc)) return INFINITY;
  const double parallax = scene.aperture_cm() / z * (fx * drop.shape().sphere_radius() / z);
  return coc + parallax;
}

bool traced_through_aperture(const SceneSample& scene, const Drop& drop, double fx, cv::Size frame) {
  if (!(scene.aperture_cm() > 0) || layer_blur_diameter(scene, drop, fx, frame) > 0) return false;
  const double spread = drop_lens_spread_px(scene, drop, fx);
  if (!std::isfinite(spread)) return false;  // centred behind the lens: left as the pinhole sees it
  const glm::dvec2 axes = drop.shape().footprint_semi_axes();
  const double z = scene.glass.point(drop.shape().center).z;
  const double radius_px = fx * std::max(axes.x, axes.y) / z;
  return shift_levels(spread, radius_px, 0.0) >= kAutoBudgetLevels;
}

DefocusedFrame composite_layers_exact(const cv::Mat& clean, const TraceResult& traced, const Camera& camera,
                                      const SceneSample& scene, const std::vector<Drop>& drops) {
  CV_Assert(clean.type() == CV_8UC3 && traced.label.size() == clean.size());
  DefocusedFrame out;
  out.coc_px.assign(drops.size(), 0.0);
  // Each drop's pixel box in the pinhole render.
  std::vector<cv::Rect> box(drops.size());
  const cv::Rect all = traced.drop_box;
  for (int y = all.y; y < all.y + all.height; ++y) {
    const int* label = traced.label.ptr<int>(y);
    for (int x = all.x; x < all.x + all.width; ++x) {
      const int d = label[x];
      if (d < 0) continue;
      box[d] = box[d].area() == 0 ? cv::Rect(x, y, 1, 1) : (box[d] | cv::Rect(x, y, 1, 1));
    }
  }
  cv::Mat A(clean.size(), CV_32F, cv::Scalar(0));
  cv::Mat C(clean.size(), CV_32FC3, cv::Scalar::all(0));
  const cv::Rect frame(0, 0, clean.cols, clean.rows);
  for (size_t d = 0; d < drops.size(); ++d) {
    if (box[d].area() == 0) continue;
    const double diameter = layer_blur_diameter(scene, drops[d], camera.fx, clean.size());
    const bool blurred = diameter > 0;
    out.coc_px[d] = diameter;
    cv::Mat kernel;
    int reach = 0;
    if (blurred) {
      blur_kernel(diameter, BlurMethod::DiskAntialiased).convertTo(kernel, CV_32F);
      reach = kernel.rows / 2;
    }
    const cv::Rect region = cv::Rect(box[d].x - reach, box[d].y - reach, box[d].width + 2 * reach,
                                     box[d].height + 2 * reach) & frame;
    cv::Mat a(region.size(), CV_32F, cv::Scalar(0)), aR(region.size(), CV_32FC3, cv::Scalar::all(0));
    for (int y = box[d].y; y < box[d].y + box[d].height; ++y) {
      const int* label = traced.label.ptr<int>(y);
      const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
      const float* cov = traced.coverage.empty() ? nullptr : traced.coverage.ptr<float>(y);
      for (int x = box[d].x; x < box[d].x + box[d].width; ++x) {
        if (label[x] != static_cast<int>(d)) continue;
        const float coverage = cov ? cov[x] : 1.0f;
        a.at<float>(y - region.y, x - region.x) = coverage;
        cv::Vec3f r;
        for (int c = 0; c < 3; ++c) {
          const float v = std::isfinite(rgb[x][c]) ? std::min(std::max(rgb[x][c], 0.0f), 1.0f) : 0.0f;
          r[c] = static_cast<float>(srgb_to_linear(v));
        }
        scene.highlights.apply(r.val);
        aR.at<cv::Vec3f>(y - region.y, x - region.x) = coverage * r;
      }
    }
    if (blurred) {
      cv::filter2D(a, a, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
      cv::filter2D(aR, aR, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
    }
    A(region) += a;
    C(region) += aR;
  }
  out.rainy = clean.clone();
  out.coverage = cv::Mat(clean.size(), CV_32F, cv::Scalar(0));
  for (int y = 0; y < clean.rows; ++y) {
    const float* a = A.ptr<float>(y);
    const auto* c = C.ptr<cv::Vec3f>(y);
    const auto* b = clean.ptr<cv::Vec3b>(y);
    float* coverage = out.coverage.ptr<float>(y);
    auto* rainy = out.rainy.ptr<cv::Vec3b>(y);
    for (int x = 0; x < clean.cols; ++x) mix_layers(a[x], c[x].val, b[x].val, scene.highlights, &coverage[x], rainy[x].val);
  }
  return out;
}

DefocusedFrame encode_aperture(const cv::Mat& clean, const ApertureResult& reference, const HighlightLift& lift) {
  DefocusedFrame out;
  if (!reference.clean_linear.empty()) {
    const cv::Mat everywhere(clean.size(), CV_32F, cv::Scalar(1));
    out.clean = encode(clean, reference.clean_linear, everywhere, lift);
  }
  out.rainy = encode(out.clean.empty() ? clean : out.clean, reference.linear, reference.coverage, lift);
  out.coverage = reference.coverage.clone();
  return out;
}

}  // namespace raindrop
