#pragma once
// One concrete scene drawn from a SceneConfig: glass pose, background distance, blur size and
// the drops, placed on the part of the glass the camera sees.
#include <cmath>
#include <vector>

#include "raindrop/common/rng.h"
#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/glass.h"
#include "raindrop/render/highlights.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

struct SceneSample {
  GlassPlane glass;
  double background_distance_cm = 1000;  // T: the background plane is z = T
  double blur_diameter_px = 0;           // at the output resolution; 0 = no blur
  // Thin-lens camera (SceneConfig::lens): f-number and physical focal length; focus on the
  // plane z = focus_cm() (the background plane unless the scene moves it). f_number 0 = pinhole.
  double f_number = 0;
  double focal_length_mm = 0;
  double focus_distance_cm = 0;  // 0: focus on the background (T)
  double aperture_cm() const { return f_number > 0 ? 0.1 * focal_length_mm / f_number : 0.0; }
  double focus_cm() const { return focus_distance_cm > 0 ? focus_distance_cm : background_distance_cm; }
  // Diameter in pixels of the circle of confusion of a point at depth z (cm) for a camera
  // with focal length fx pixels: aperture * fx * |1/z - 1/F| (thin lens, focus at F).
  double coc_px(double z, double fx) const {
    return aperture_cm() * fx * std::abs(1.0 / z - 1.0 / focus_cm());
  }
  // The background plane's own circle of confusion: 0 when focus is on it.
  double background_coc_px(double fx) const {
    return focus_distance_cm > 0 ? coc_px(background_distance_cm, fx) : 0.0;
  }
  // The circle of confusion of a drop, from the depth of its footprint's centre; infinite
  // for a centre at or behind the lens (only a degenerate scene puts one there).
  double drop_coc_px(const DropShape& d, double fx) const {
    const double z = glass.point(d.center).z;
    return z > 0 ? coc_px(z, fx) : INFINITY;
  }
  // The highlights' lift (SceneConfig::highlights; off unless the scene names it). Its gain is
  // drawn after everything else, so turning it on changes no other draw of the sample.
  HighlightLift highlights;
  std::vector<DropShape> drops;
  int drops_requested = 0;               // may exceed drops.size() if the glass was too full
};

// Drop centres are uniform per unit area of glass over the region seen through the frame
// (plus a margin, so drops may be cut by the frame edge); footprints do not overlap unless
// the config allows it, and then each overlaps at most 4 others (scene.cpp: kMaxOverlaps).
// Deterministic in the Rng state.
SceneSample sample_scene(const SceneConfig& config, const Camera& camera, Rng& rng);

// A value drawn uniformly from the range (its one value when lo == hi, drawing nothing).
double draw(const Range& r, Rng& rng);

}  // namespace raindrop
