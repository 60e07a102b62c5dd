#pragma once
// The thin-lens camera's fast path: layered compositing. The drops are traced once through
// the centre of the aperture (the pinhole render: each drop's radiance R_d and its coverage
// a_d, 1 on its image and 0 elsewhere); each drop's layer is then spread by the disk of its
// own circle of confusion (from the depth of its centre on the glass), and the layers are
// composited over the clean frame in linear light. Drops in focus (circles under half a
// pixel), whose layers are not spread, are traced through the aperture where it shows
// (traced_through_aperture): their R_d is the mean of a pixel's rays from the lens disk and
// a_d the fraction of them that met the drop (tracer.h, LensTrace).
// The sums:
//     A = sum_d blur_d(a_d),   I = (1 - A) B + sum_d blur_d(a_d R_d)
// (A clamped to 1 where blurred drops overlap). A drop smaller than its circle of confusion
// so never reaches A = 1: it is semi-transparent, and its image spreads beyond its outline,
// as in real photographs. What this ignores, against the aperture reference (tracer.h,
// trace_aperture): the parallax of the drop's view across the aperture and the blur's
// variation inside one drop; the accuracy/time table measures the difference.
//
// Two implementations of the same sums: composite_layers spreads every layer with the disk's
// rows (disk_kernel.h: a prefix-sum run and the rim's partial taps per row, O(d) per pixel),
// output row by output row on all threads, and touches only the rows and columns a layer can
// reach; circles of 48-96 px it spreads so at every second or third pixel and interpolates
// between (unless the drop sees lifted highlights), circles of 96 px and more on a coarser
// grid (defocus_rows.cpp).
// composite_layers_exact convolves each drop's layer with the dense disk by cv::filter2D, one
// drop after another (the method before; `"defocus": "layered-exact"`). They agree to float
// rounding below 48 px, within 4/255 in coverage and four levels of the image at 48-96 px, and
// within 1/255 and two levels above (tests/render/test_defocus.cpp).
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/tracer.h"

namespace raindrop {

struct DefocusedFrame {
  cv::Mat rainy;              // CV_8UC3: equal to the clean bytes wherever coverage is 0
  cv::Mat clean;              // CV_8UC3: the street as the lens sees it, where the reference traced it; else empty
  cv::Mat coverage;           // CV_32F in [0, 1]: the fraction of the aperture that sees a drop
  std::vector<double> coc_px; // per drop: circle-of-confusion diameter used (0: not blurred)
};

// Drops whose circle of confusion is below this many pixels are not blurred: the blur would
// change no pixel by more than rounding (the `auto` rule of the thin-lens camera).
inline constexpr double kMinVisibleCocPx = 0.5;

// The diameter (pixels) of the disk that spreads `drop`'s layer; 0: left sharp (a circle under
// kMinVisibleCocPx, or a drop centred behind the lens, whose circle is infinite). Bounded by
// twice the frame's longer side, so that a pathological scene cannot ask for a kernel wider
// than the frame per drop (the blur is then simply as wide as the frame).
double layer_blur_diameter(const SceneSample& scene, const Drop& drop, double fx, cv::Size frame);

// How far, in pixels, the aperture moves what a drop shows inside when its layer is not blurred
// (a circle under kMinVisibleCocPx): the circle itself, which a drop does not hide as its
// outline does (it shows the street minified many times, so a fraction of a pixel on the glass
// is a wide patch of that view), plus the parallax of the drop across the aperture: its rays
// arrive over the angle aperture / depth, which turns the view refracted through the cap and
// moves the dark band's edge by up to that angle times the cap's sphere radius.
double drop_lens_spread_px(const SceneSample& scene, const Drop& drop, double fx);

// Whether the layered path traces a drop through the aperture (tracer.h, LensTrace::sampled)
// instead of through the lens' centre alone: the lens has an aperture, the drop's layer is not
// blurred, and its spread changes a pixel inside it by the auto budget or more
// (effect_policy.h: shift_levels, kAutoBudgetLevels). A pinhole-sized aperture stays the pinhole.
bool traced_through_aperture(const SceneSample& scene, const Drop& drop, double fx, cv::Size frame);

// One layer (CV_32FC4: R, G, B and coverage, premultiplied, in linear light) spread by the
// disk of `diameter` pixels, as composite_layers spreads a drop's layer whose circle is
// exact (not coarse); for tests.
cv::Mat spread_layer(const cv::Mat& values, double diameter);

// `traced`: the pinhole trace of `drops` over `clean` (CV_8UC3 RGB). Runs on the calling
// thread's TBB arena; the result does not depend on the number of threads.
DefocusedFrame composite_layers(const cv::Mat& clean, const TraceResult& traced, const Camera& camera,
                                const SceneSample& scene, const std::vector<Drop>& drops);

// The same with one cv::filter2D per drop and dense kernels: the reference the fast path is
// tested against, and the bench's "layered-exact" row.
DefocusedFrame composite_layers_exact(const cv::Mat& clean, const TraceResult& traced, const Camera& camera,
                                      const SceneSample& scene, const std::vector<Drop>& drops);

// The reference's result in the same form: linear radiance where coverage > 0 (stored through
// `lift`'s inverse where it lifted the light it traced; highlights.h), the clean bytes elsewhere.
// With the street traced (clean_linear), the clean bytes are its encoding, returned as `clean`.
DefocusedFrame encode_aperture(const cv::Mat& clean, const ApertureResult& reference, const HighlightLift& lift = {});

}  // namespace raindrop
