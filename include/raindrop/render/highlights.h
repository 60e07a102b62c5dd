#pragma once
// Highlights: clipped pixels lifted back towards the light they stood for, before the lens
// spreads it (scene effect "highlights", with a thin-lens camera only).
//
// A photograph clips: a lamp, the sun on a windscreen or a bright sky that was ten times
// brighter than full scale is stored as 255. Spread over a drop's circle of confusion, the
// stored value says the light was weak, so our drops darkened every highlight they covered: on
// lens-cover-merged renders the rainy image has a median 1% as many clipped pixels as the clean
// one, where a real wet lens has 97% (docs/RESULTS.md 4.12), and a night lamp behind a drop would
// make a grey smudge instead of a bloom. The lift undoes the clip in linear light, where light
// adds: a pixel whose brightest channel m (decoded) is above the threshold t is scaled by
//     g(m) = 1 + (gain - 1) u^2,  u = (m - t) / (1 - t),
// so g = 1 at t (continuously, with a continuous slope), g = gain at full scale, m g(m)
// increasing, and the ratios between channels (the hue) kept. Everything the lens mixes (the
// drops' radiance and the street around them) is lifted, mixed, and then stored again through
// the camera's response that the lift undid: restore() inverts L(m) = m g(m) (a soft shoulder
// that reaches full scale at `gain`), so that a pixel the drops barely reach keeps its stored
// value (a hard clip after the mix would turn every unclipped 235-249 into 255 the moment a
// blur's faintest edge touched it), a lamp behind a drop blooms, and the part of a clipped sky
// that most of the aperture still sees stays near full scale.
#include <algorithm>

namespace raindrop {

struct HighlightLift {
  float threshold = 1.0f;  // linear light: the brightest channel above it is lifted
  float gain = 1.0f;       // the factor at full scale; 1: the lift is off

  bool active() const { return gain > 1.0f && threshold < 1.0f; }

  // The factor for a pixel whose brightest channel is m (linear, in [0, 1]).
  float factor(float m) const {
    if (!(m > threshold)) return 1.0f;
    const float u = std::min(1.0f, (m - threshold) / (1.0f - threshold));
    return 1.0f + (gain - 1.0f) * u * u;
  }

  // Lifts linear RGB in place (a no-op unless active()).
  template <typename T>
  void apply(T* rgb) const {
    if (!active()) return;
    const T f = factor(static_cast<float>(std::max(rgb[0], std::max(rgb[1], rgb[2]))));
    rgb[0] *= f;
    rgb[1] *= f;
    rgb[2] *= f;
  }

  // The stored value m in [0, 1] whose lift m factor(m) is `light` (>= 0): the inverse of the
  // lift, 1 from `gain` up (the camera's clip). L is convex and increasing above the threshold,
  // so Newton's method from m = 1 converges from above without overshooting.
  float unlift(float light) const {
    if (!(light > threshold)) return light;  // also NaN: left to the encoder
    if (light >= gain) return 1.0f;
    double m = 1.0;
    const double t = threshold, g = gain, w = 1.0 - t;
    for (int i = 0; i < 20; ++i) {
      const double u = (m - t) / w;
      const double lifted = m * (1.0 + (g - 1.0) * u * u);
      const double slope = 1.0 + (g - 1.0) * u * u + m * (g - 1.0) * 2.0 * u / w;
      const double step = (lifted - light) / slope;
      m -= step;
      if (step < 1e-7) break;
    }
    return static_cast<float>(std::max(m, t));
  }

  // Stores mixed linear light again (in place): the brightest channel M becomes unlift(M) and
  // the others keep their ratio to it (a no-op unless active()).
  template <typename T>
  void restore(T* rgb) const {
    if (!active()) return;
    const T brightest = std::max(rgb[0], std::max(rgb[1], rgb[2]));
    if (!(brightest > threshold)) return;
    const T f = static_cast<T>(unlift(static_cast<float>(brightest))) / brightest;
    rgb[0] *= f;
    rgb[1] *= f;
    rgb[2] *= f;
  }
};

}  // namespace raindrop
