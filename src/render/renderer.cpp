#include "raindrop/render/renderer.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <opencv2/core.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/common/stopwatch.h"
#include "raindrop/render/background_defocus.h"
#include "raindrop/render/blur.h"
#include "raindrop/render/defocus.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/render/srgb.h"

namespace raindrop {
namespace {

// The thin-lens camera: layered compositing (fast, or its exact per-drop form) or aperture
// sampling (reference).
// A drop just outside the frame still spreads light into it, so both run on the frame
// widened by the largest circle's radius (the clean frame mirrored into the margin, as the
// border mode continues it) and are cropped back.
// The reference traces the street too where focus is off it (tracer.h): `clean` is then the
// sharp input, the margin as wide as the street's circle too, and the clean image its own.
// The layered path's drops in focus (`lens.sampled`) are traced to `sharp`, the input before
// the street's defocus (the same as `clean` where the street is in focus).
RenderedFrame render_defocused(const cv::Mat& clean, const cv::Mat& sharp, const Camera& camera,
                               const SceneConfig& config, const SceneSample& scene, const DropAccel& accel,
                               const std::vector<Drop>& drops, double largest_coc_px, LensTrace lens,
                               RenderedFrame frame) {
  frame.defocused = true;
  if (config.lens.method == DefocusMethod::Aperture)
    largest_coc_px = std::max(largest_coc_px, scene.background_coc_px(camera.fx));
  const int pad = static_cast<int>(std::ceil(std::min(0.5 * largest_coc_px, 0.5 * std::max(clean.cols, clean.rows)))) + 1;
  cv::Mat wide;
  cv::copyMakeBorder(clean, wide, pad, pad, pad, pad,
                     config.border == BorderMode::Clamp ? cv::BORDER_REPLICATE : cv::BORDER_REFLECT);
  const Camera wide_camera = camera.cropped(-pad, -pad, clean.cols + 2 * pad, clean.rows + 2 * pad);
  const cv::Rect inner(pad, pad, clean.cols, clean.rows);
  auto t0 = Clock::now();
  DefocusedFrame out;
  if (config.lens.method == DefocusMethod::Aperture) {
    out = encode_aperture(wide,
                          trace_aperture(wide, wide_camera, config, scene, accel, config.lens.aperture_samples,
                                         &frame.effects, {}, pad),
                          scene.highlights);
    frame.timings.trace_ms = ms_since(t0);
    for (const Drop& d : drops) out.coc_px.push_back(scene.drop_coc_px(d.shape(), camera.fx));
  } else {
    lens.margin = pad;
    cv::Mat sharp_wide;
    if (lens.any_sampled() && sharp.data != clean.data) {
      cv::copyMakeBorder(sharp, sharp_wide, pad, pad, pad, pad,
                         config.border == BorderMode::Clamp ? cv::BORDER_REPLICATE : cv::BORDER_REFLECT);
      lens.sharp = &sharp_wide;
    }
    const TraceResult traced = trace_drops(wide, wide_camera, config, scene, accel, &frame.effects, {}, &lens);
    frame.stats = traced.stats;
    frame.timings.trace_ms = ms_since(t0);
    t0 = Clock::now();
    out = config.lens.method == DefocusMethod::LayeredExact
              ? composite_layers_exact(wide, traced, wide_camera, scene, drops)
              : composite_layers(wide, traced, wide_camera, scene, drops);
    frame.timings.blur_ms = ms_since(t0);
  }
  t0 = Clock::now();
  if (!out.clean.empty()) frame.clean = out.clean(inner).clone();
  frame.coc_px = std::move(out.coc_px);
  // The crop, and the binary mask (coverage >= the scene's threshold, 0/255) with its count, in
  // one pass over the rows on all threads: each row's coverage is still in the cache when it is
  // thresholded.
  frame.rainy.create(clean.size(), CV_8UC3);
  frame.alpha.create(clean.size(), CV_32F);
  frame.mask.create(clean.size(), CV_8U);
  const float threshold = static_cast<float>(config.lens.mask_threshold);
  std::atomic<std::int64_t> masked{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, clean.rows, 16), [&](const tbb::blocked_range<int>& r) {
    std::int64_t n = 0;
    for (int y = r.begin(); y < r.end(); ++y) {
      std::memcpy(frame.rainy.ptr(y), out.rainy.ptr<cv::Vec3b>(inner.y + y) + inner.x, 3 * static_cast<size_t>(clean.cols));
      const float* a = out.coverage.ptr<float>(inner.y + y) + inner.x;
      std::memcpy(frame.alpha.ptr(y), a, sizeof(float) * static_cast<size_t>(clean.cols));
      std::uint8_t* m = frame.mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < clean.cols; ++x) {
        m[x] = a[x] >= threshold ? 255 : 0;
        n += a[x] >= threshold;
      }
    }
    masked += n;
  });
  frame.stats.drop_pixels = masked;
  frame.timings.compose_ms = ms_since(t0);
  return frame;
}

// Whether the highlights' lift (highlights.h) can change the frame: some channel of some pixel,
// of the sky that refracted rays see, or of the car's interior that Fresnel reflection mixes in,
// decodes above its threshold. A traced colour is a mix of those, so it is lifted only if one
// of them is.
bool highlights_present(const cv::Mat& clean, const SceneConfig& config, const HighlightLift& lift) {
  const auto& lin = srgb8_to_linear_table();
  int first_lifted = 256;  // the smallest 8-bit code the lift changes
  for (int c = 255; c >= 0 && lin[c] > lift.threshold; --c) first_lifted = c;
  double brightest = 0;
  cv::minMaxLoc(clean.reshape(1), nullptr, &brightest);
  if (brightest >= first_lifted) return true;
  auto lifted = [&](const glm::dvec3& rgb) {
    return srgb_to_linear(std::max(rgb.x, std::max(rgb.y, rgb.z))) > lift.threshold;
  };
  if (config.fresnel.enabled && lifted(config.fresnel.interior_rgb)) return true;
  // The sky is a mean of the frame's pixels times its gain (sky.h), so never brighter than this
  // bound, whichever frame (this one or the tracer's widened copy) it is estimated from.
  return config.sky.enabled && lifted(glm::dvec3(std::min(1.0, brightest / 255.0 * config.sky.gain)));
}

}  // namespace

double RenderedFrame::coverage() const {
  return mask.empty() ? 0.0 : static_cast<double>(stats.drop_pixels) / (mask.total());
}

RenderedFrame render_frame(const cv::Mat& input, const Camera& camera, const SceneConfig& config,
                           const SceneSample& scene) {
  RenderedFrame frame;
  // What the lens spreads, from the sample alone: the drops, where some drop's circle of
  // confusion reaches half a pixel (else the pinhole render is what the lens would give, to
  // rounding), and the street, where focus is off it and its own circle reaches half a pixel.
  double largest = 0;
  const bool lens = config.lens.enabled && scene.aperture_cm() > 0;
  if (lens) {
    for (const DropShape& d : scene.drops) largest = std::max(largest, scene.drop_coc_px(d, camera.fx));
  }
  const bool defocus = lens && largest >= kMinVisibleCocPx;
  const double background_coc = lens ? scene.background_coc_px(camera.fx) : 0.0;
  const bool street_defocused = background_coc >= kMinVisibleCocPx;
  // Highlights run where the lens spreads something, the scene names them (the config decides,
  // whatever the sample was drawn with) and some pixel of the input reaches the threshold.
  const bool lift = (defocus || street_defocused) && config.highlights.enabled && scene.highlights.active() &&
                    highlights_present(input, config, scene.highlights);
  frame.highlights_lifted = lift;

  // Focus off the background: the street is defocused (background_defocus.h), and the drops are
  // traced and composited against it; the aperture reference traces the street's defocus
  // instead, from the input. Otherwise the input is the background as it is.
  const bool street_traced = street_defocused && config.lens.method == DefocusMethod::Aperture;
  auto t0 = Clock::now();
  if (street_defocused && !street_traced)
    frame.clean = defocus_background(input, background_coc, config.border, lift ? scene.highlights : HighlightLift{});
  frame.timings.background_ms = ms_since(t0);
  const cv::Mat& clean = frame.clean.empty() ? input : frame.clean;
  t0 = Clock::now();
  // The effects the scene leaves to its physics ("auto"), per drop; gravity is undone on the
  // drops where it does not show.
  frame.effects = plan_effects(config, scene, camera, defocus || street_traced);
  std::vector<Drop> drops;
  drops.reserve(scene.drops.size());
  for (const DropShape& shape : rendered_shapes(scene, frame.effects)) drops.emplace_back(shape, scene.glass);
  DropAccel accel(drops, config.geometry);
  accel.set_disjoint(config.drops_disjoint());
  frame.timings.accel_ms = ms_since(t0);

  // Drops in focus: a circle under half a pixel leaves a drop's outline where the pinhole puts
  // it, but not what it shows inside (defocus.h). Where that shows, the layered path's pixels
  // near them average rays from the aperture (tracer.h, LensTrace), and the reference, which
  // traces every drop so, runs even though no circle reaches half a pixel.
  std::vector<char> in_focus;
  if (lens && (config.lens.method == DefocusMethod::Aperture || config.lens.trace_in_focus)) {
    in_focus.reserve(drops.size());
    for (const Drop& d : drops) in_focus.push_back(traced_through_aperture(scene, d, camera.fx, input.size()));
  }
  for (char d : in_focus) frame.lens_sampled_drops += d != 0;
  frame.lens_sampled = frame.lens_sampled_drops > 0;
  LensTrace sampling;
  sampling.samples = config.lens.aperture_samples;
  if (config.lens.method != DefocusMethod::Aperture) sampling.sampled = std::move(in_focus);

  if (defocus || street_traced || frame.lens_sampled) {
    // Without the lift, a copy of the sample with it off renders the frame exactly as without
    // the effect, at its cost.
    if (lift || !scene.highlights.active())
      return render_defocused(clean, input, camera, config, scene, accel, drops, largest, sampling, frame);
    SceneSample unlifted = scene;
    unlifted.highlights = HighlightLift{};
    return render_defocused(clean, input, camera, config, unlifted, accel, drops, largest, sampling, frame);
  }

  t0 = Clock::now();
  TraceResult traced = trace_drops(clean, camera, config, scene, accel, &frame.effects);
  frame.timings.trace_ms = ms_since(t0);
  frame.stats = traced.stats;

  t0 = Clock::now();
  if (config.blur.enabled) {
    blur_drops(clean, traced.label, traced.color, scene.blur_diameter_px, config.blur.method, &traced.drop_box, &traced.spans);
  }
  frame.timings.blur_ms = ms_since(t0);

  // Only drop pixels are written: everywhere else the rainy image is the clean bytes.
  // Rows in parallel, the copy of the clean bytes included: one thread copying 6 MB and
  // zeroing 2 MB was a twelfth of a 2048x1024 frame's core on two threads.
  t0 = Clock::now();
  frame.rainy.create(clean.size(), clean.type());
  frame.mask.create(clean.size(), CV_8UC1);
  tbb::parallel_for(tbb::blocked_range<int>(0, clean.rows, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const int* label = traced.label.ptr<int>(y);
      const auto* rgb = traced.color.ptr<cv::Vec3f>(y);
      auto* out = frame.rainy.ptr<cv::Vec3b>(y);
      auto* m = frame.mask.ptr<std::uint8_t>(y);
      std::memcpy(static_cast<void*>(out), clean.ptr<std::uint8_t>(y), 3 * static_cast<size_t>(clean.cols));
      std::memset(m, 0, clean.cols);
      for (const auto& [x0, x1] : traced.spans[y]) for (int x = x0; x <= x1; ++x) {
        if (label[x] < 0) continue;
        m[x] = 255;
        for (int c = 0; c < 3; ++c) {
          const float v = std::isfinite(rgb[x][c]) ? rgb[x][c] : 0.0f;
          out[x][c] = static_cast<std::uint8_t>(std::floor(std::min(std::max(v, 0.0f), 1.0f) * 255.0f + 0.5f));
        }
      }
    }
  });
  frame.timings.compose_ms = ms_since(t0);
  return frame;
}

}  // namespace raindrop
