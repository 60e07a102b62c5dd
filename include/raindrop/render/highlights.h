#pragma once
// Highlights: clipped pixels lifted back towards the light they stood for, before the lens
// spreads it (scene effect "highlights", with a thin-lens camera only).
//
// A photograph clips: a lamp, the sun on a windscreen or a bright sky that was ten times
// brighter than full scale is stored as 255. Spread over a drop's circle of confusion, the
// stored value says the light was weak, so our drops darkened every highlight they covered: on
// lens-cover renders 93% of the frame's saturated pixels were gone in the rainy image, where a
// real wet lens keeps 95% of them (docs/RESULTS.md 4.12), and a night lamp behind a drop would
// make a grey smudge instead of a bloom. The lift undoes the clip in linear light, where light
// adds: a pixel whose brightest channel m (decoded) is above the threshold t is scaled by
//     g(m) = 1 + (gain - 1) u^2,  u = (m - t) / (1 - t),
// so g = 1 at t (continuously, with a continuous slope), g = gain at full scale, m g(m)
// increasing, and the ratios between channels (the hue) kept. Everything the lens mixes (the
// drops' radiance and the street around them) is lifted, mixed, then encoded with the clip the
// camera applies, so a pixel no drop reaches keeps its bytes, and one that only part of the
// aperture sees through a drop in front of a lamp stays as clipped as the lamp.
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
};

}  // namespace raindrop
