// Drops in focus traced through the aperture (tracer.h, LensTrace; defocus.h,
// traced_through_aperture): the layered path against the aperture reference where every drop's
// circle is under half a pixel, the budget rule that skips it for pinhole-sized apertures, and
// the widened frame's border continued from the frame itself (BackgroundSampler::set_margin).
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "raindrop/common/demo.h"
#include "raindrop/common/rng.h"
#include "raindrop/render/background.h"
#include "raindrop/render/defocus.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

constexpr double kT = 1000;  // background plane, cm

// A window beaded with small drops, 30 cm away and tilted 10 degrees off upright, seen at f/2
// with the focus on it: every drop's circle is under half a pixel (the tilt moves them off the
// plane of focus by a fraction of a pixel), while the street's circle is several pixels.
SceneSample beaded_window(double f_number) {
  SceneSample s = lens_sample(30, f_number, 5, kT);
  s.glass.tilt = 80 * kDegToRad;
  s.focus_distance_cm = 30;
  int i = 0;
  for (double v : {-2.6, -0.8, 1.0, 2.8}) {
    for (double u : {-6.0, -3.5, -1.0, 1.5, 4.0, 6.5}) {
      s.drops.push_back(cap(u + 0.4 * (i % 3), v, 0.12 + 0.03 * (i % 4), 30 + 5 * (i % 4)));
      ++i;
    }
  }
  return s;
}

SceneConfig config(DefocusMethod method, int samples) {
  SceneConfig c = lens_scene(method);
  c.lens.focus = SceneConfig::Focus::Distance;
  c.lens.aperture_samples = samples;
  return c;
}

// RMS difference in 8-bit levels over the pixels some drop covers in either render.
double rms_in_drops(const RenderedFrame& a, const RenderedFrame& b) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < a.rainy.rows; ++y) {
    for (int x = 0; x < a.rainy.cols; ++x) {
      if (!(a.alpha.at<float>(y, x) > 0.01f || b.alpha.at<float>(y, x) > 0.01f)) continue;
      for (int c = 0; c < 3; ++c) {
        const double d = a.rainy.at<cv::Vec3b>(y, x)[c] - b.rainy.at<cv::Vec3b>(y, x)[c];
        sum += d * d;
      }
      n += 3;
    }
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

}  // namespace

// What a drop in focus shows is spread by the aperture although its circle is under half a
// pixel: traced through the aperture, the layered path follows the reference (256 rays) inside
// the drops to within the sampling noise of its own 16 rays; the pinhole trace of the same drops
// over the same defocused street (the layered path before) is several times farther.
TEST(LensTrace, DropsInFocusFollowTheApertureReference) {
  const Camera cam = camera(321, 161, 600);
  const cv::Mat street = demo_street(cam.width, cam.height);
  const SceneSample s = beaded_window(2);
  for (const DropShape& d : s.drops) {
    ASSERT_LT(s.drop_coc_px(d, cam.fx), kMinVisibleCocPx);
  }
  ASSERT_GT(s.background_coc_px(cam.fx), 2.0);
  const RenderedFrame reference = render_frame(street, cam, config(DefocusMethod::Aperture, 256), s);
  const RenderedFrame layered = render_frame(street, cam, config(DefocusMethod::Layered, 16), s);
  ASSERT_TRUE(layered.lens_sampled);
  ASSERT_FALSE(layered.clean.empty());
  // The drops traced through the lens' centre over the same defocused street (`"drops_in_focus":
  // "centre"`, the layered path before): the pinhole render, whose coverage is its mask.
  SceneConfig through_centre_config = config(DefocusMethod::Layered, 16);
  through_centre_config.lens.trace_in_focus = false;
  RenderedFrame centre = render_frame(street, cam, through_centre_config, s);
  ASSERT_FALSE(centre.lens_sampled);
  ASSERT_TRUE(equal_bits(centre.clean, layered.clean));
  if (centre.alpha.empty()) centre.mask.convertTo(centre.alpha, CV_32F, 1.0 / 255);
  // The yardstick: the reference's own 16 rays against its 256.
  const RenderedFrame reference16 = render_frame(street, cam, config(DefocusMethod::Aperture, 16), s);
  const double traced = rms_in_drops(layered, reference), through_centre = rms_in_drops(centre, reference);
  const double noise = rms_in_drops(reference16, reference);
  std::printf("inside the drops against 256 rays: traced through the aperture %.2f, through its centre %.2f, the "
              "reference at 16 rays %.2f levels RMS\n", traced, through_centre, noise);
  EXPECT_LT(traced, 1.5 * noise);
  EXPECT_GT(through_centre, 2.0 * traced);
  // The outline stays the pinhole's: the masks differ by at most a pixel's ring.
  EXPECT_LT(cv::countNonZero(layered.mask != centre.mask), 0.1 * cv::countNonZero(centre.mask));
}

// The rule that decides it, against the converged image it is stated for (effect_policy.h: each
// pixel's area sampled 256 times as well as the lens, so that one ray is one level): a drop whose spread is under the budget is
// left to the pinhole, and tracing it through the aperture anyway changes its pixels by under
// half a level RMS and under 4 levels in every channel, against the same rays through a
// pinhole-sized aperture. Where the rule traces a drop, skipping it would break that tolerance.
// A pinhole-sized aperture itself stays the pinhole (Defocus.TinyApertureReproducesThePinholeRender
// holds it bit for bit).
TEST(LensTrace, DropsWhoseSpreadIsUnderTheBudgetAreLeftToThePinhole) {
  const Camera cam = camera(321, 161, 600);
  const cv::Mat street = demo_street(cam.width, cam.height);
  int skipped = 0, kept = 0, kept_visible = 0, kept_wide = 0, kept_wide_visible = 0;
  double skipped_sq = 0, skipped_worst = 0;
  long skipped_n = 0;
  for (double f_number : {2.0, 16.0, 64.0, 256.0, 1024.0}) {
    // Glass far enough (3 m, the street at 10 m, in focus) that the circles stay under half a
    // pixel, drops big enough (2-4 px across) to show the street inside them.
    SceneSample s = beaded_window(f_number);
    s.focus_distance_cm = 0;
    s.glass.tilt = M_PI / 2;
    s.glass.distance = 300;
    std::vector<Drop> drops;
    for (DropShape d : s.drops) {
      d.center *= 10.0;
      d.footprint_radius *= 10.0;
      drops.emplace_back(d, s.glass);
    }
    s.drops.clear();
    for (const Drop& d : drops) s.drops.push_back(d.shape());
    SceneSample pinhole_sized = s;
    pinhole_sized.f_number = 1e9;
    DropAccel accel(drops, GeometryOptions{});
    accel.set_disjoint(true);
    LensTrace all;
    all.samples = 256;
    all.sampled.assign(drops.size(), 1);
    SceneConfig c = config(DefocusMethod::Layered, 256);
    c.samples_per_pixel = 256;
    const TraceResult a = trace_drops(street, cam, c, s, accel, nullptr, {}, &all);
    const TraceResult b = trace_drops(street, cam, c, pinhole_sized, accel, nullptr, {}, &all);
    const DefocusedFrame fa = composite_layers(street, a, cam, s, drops);
    const DefocusedFrame fb = composite_layers(street, b, cam, pinhole_sized, drops);
    for (size_t i = 0; i < drops.size(); ++i) {
      ASSERT_LT(s.drop_coc_px(drops[i].shape(), cam.fx), kMinVisibleCocPx) << f_number;
      const bool traced = traced_through_aperture(s, drops[i], cam.fx, street.size());
      double worst = 0;
      for (int y = 0; y < cam.height; ++y) {
        for (int x = 0; x < cam.width; ++x) {
          if (a.label.at<int>(y, x) != static_cast<int>(i) && b.label.at<int>(y, x) != static_cast<int>(i)) continue;
          for (int ch = 0; ch < 3; ++ch) {
            const double d = double(fa.rainy.at<cv::Vec3b>(y, x)[ch]) - fb.rainy.at<cv::Vec3b>(y, x)[ch];
            worst = std::max(worst, std::abs(d));
            if (!traced) skipped_sq += d * d, ++skipped_n;
          }
        }
      }
      if (traced) {
        ++kept;
        kept_visible += worst > 4;
        kept_wide += f_number == 2.0;
        kept_wide_visible += f_number == 2.0 && worst > 4;
      } else {
        ++skipped;
        skipped_worst = std::max(skipped_worst, worst);
      }
    }
  }
  const double skipped_rmse = skipped_n > 0 ? std::sqrt(skipped_sq / skipped_n) : 0.0;
  std::printf("%d drops left to the pinhole: %.2f levels RMS, %.0f at most when traced anyway; %d traced, %d of them "
              "4 levels or more off a pinhole-sized aperture\n",
              skipped, skipped_rmse, skipped_worst, kept, kept_visible);
  EXPECT_GT(skipped, 0);
  EXPECT_LT(skipped_rmse, 0.5);
  EXPECT_LT(skipped_worst, 4.0);
  // The budget is half the tolerance, so the drops just above it need not break the tolerance;
  // at f/2 every drop does.
  EXPECT_GT(kept_wide, 0);
  EXPECT_EQ(kept_wide_visible, kept_wide);
}

// The thin-lens paths widen the frame by a margin (its mirror or its edge continued) so that
// drops just outside still spread into it. A ray that leaves the widened image sees the frame's
// own continuation and the sky above the frame's top, whatever the margin: the same colours as
// the frame alone at the same point, also where the coordinates are not finite.
TEST(LensTrace, AWidenedFrameIsContinuedFromTheFrameItself) {
  const cv::Mat frame = demo_street(37, 23);
  Rng rng(5);
  for (BorderMode mode : {BorderMode::Mirror, BorderMode::Clamp}) {
    BackgroundSampler alone(frame, mode);
    alone.set_sky(glm::dvec3(0.2, 0.5, 0.9), 6.0);
    for (int margin : {1, 4, 9}) {
      cv::Mat wide;
      cv::copyMakeBorder(frame, wide, margin, margin, margin, margin,
                         mode == BorderMode::Clamp ? cv::BORDER_REPLICATE : cv::BORDER_REFLECT);
      BackgroundSampler widened(wide, mode);
      widened.set_margin(margin);
      widened.set_sky(glm::dvec3(0.2, 0.5, 0.9), 6.0);
      double worst = 0;
      for (int i = 0; i < 4000; ++i) {
        const double x = rng.uniform(-200.0, 240.0), y = rng.uniform(-150.0, 170.0);
        const glm::dvec3 d = alone.sample(x, y) - widened.sample(x + margin, y + margin);
        worst = std::max({worst, std::abs(d.x), std::abs(d.y), std::abs(d.z)});
        EXPECT_EQ(alone.inside(x, y), widened.inside(x + margin, y + margin));
      }
      // Coordinates that are not finite (a ray parallel to the street) land on the frame's corner
      // pixels, not the margin's.
      for (double x : {-HUGE_VAL, HUGE_VAL, std::nan(""), 10.0}) {
        for (double y : {-HUGE_VAL, HUGE_VAL, std::nan(""), 10.0}) {
          const glm::dvec3 d = alone.sample(x, y) - widened.sample(x + margin, y + margin);
          worst = std::max({worst, std::abs(d.x), std::abs(d.y), std::abs(d.z)});
        }
      }
      EXPECT_LT(worst, 1e-12) << "margin " << margin << (mode == BorderMode::Clamp ? " clamp" : " mirror");
    }
  }
}
