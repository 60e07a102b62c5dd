#pragma once
// Effects chosen by the scene's physics ("auto" in a scene file, docs/SCENES.md).
//
// An effect the scene marks `auto` is simulated only where it is perceptible at the output
// resolution. Each criterion estimates how far skipping the effect would move what a drop
// shows, in output pixels, and turns that displacement into the largest change it can make
// to an 8-bit pixel: content of full contrast moved by `shift` px inside a drop blurred by a
// disk `b` px wide changes a pixel by at most 255 x (area the shift sweeps inside the disk)
// / (the disk's area). An effect whose change stays under kAutoBudgetLevels is skipped.
//
//  - dispersion, per drop: the shift between the red and the blue image inside the drop,
//    from its size in pixels, contact angle, viewing angle and the index difference;
//  - gravity, per drop: the shift of the image and outline between the deformed cap and the
//    spherical one;
//  - supersampling, per pixel (tracer.cpp): a drop shows the street minified, so one ray
//    samples one point of a wide footprint on the background; a pixel keeps one ray where
//    the background varies over its footprint by less than the budget (background_range.h),
//    since any number of rays there averages to within that of the one;
//  - defocus: the thin lens' own rule (defocus.h, circles of confusion under half a pixel).
//
// The bound is for the converged image (what a pixel integrates): at one sample per pixel the
// inside of a drop aliases, and a shift of a fraction of a pixel there moves each sample to
// another point of the street.
#include <string>
#include <vector>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

// The largest change, in 8-bit levels, that skipping an effect may make to a pixel. Half the
// tolerance the tests hold auto to (4 levels), for the approximations of the estimates below.
inline constexpr double kAutoBudgetLevels = 2.0;
// The contrast assumed inside a drop: the dark band (0) next to the brightest street.
inline constexpr double kDropContrastLevels = 255.0;

// The largest change in 8-bit levels when content of contrast kDropContrastLevels inside a
// drop of radius `radius_px` moves by `shift_px`, seen through a disk blur `blur_px` wide
// (0: none; a pixel is then the unit square). An edge under a disk of diameter b has a slope
// of at most 4 / (pi b) of its contrast per pixel.
double shift_levels(double shift_px, double radius_px, double blur_px);

// Dispersion: how far apart the images of indices n - dn/2 and n + dn/2 lie inside a cap of
// sphere radius `sphere_radius_px` (seen square on) and contact angle `contact_angle`, whose
// base the camera's ray meets at `incidence` (radians). In the plane of incidence, with the
// background far (the exit ray's direction alone decides what is seen): at a point v of the
// base, the ray runs inside the water at r0, leaves the cap where its normal is tilted by
// theta, at incidence alpha = r0 - theta and angle beta (sin beta = n sin alpha), heading
// psi = theta + beta. A change of index turns r0, which moves both the exit point and alpha;
// the shift is dn (dpsi/dn) / (dpsi/dv), maximised over the cap, and the dark band's edge
// moves with the critical angle. Within a few per cent of traced rays (tests).
double dispersion_spread_px(double sphere_radius_px, double contact_angle, double incidence, double n, double dn);

// Gravity: the shift between a cap stretched downhill by `elongation` and flattened by
// `flattening` and the spherical cap of the same footprint radius `footprint_radius_px`. The
// image inside a drop is set by its surface slopes: the deformed cap has the slope of the
// sphere at v scaled by flattening / elongation at v x elongation, so (paraxially) the view
// seen at v on the sphere is seen at v x elongation^2 / flattening, which moves content at the
// rim by a x (elongation - flattening / elongation); the outline moves by less.
double gravity_shift_px(double footprint_radius_px, double elongation, double flattening);

// What the criteria found for one drop.
struct DropEffects {
  double radius_px = 0;      // the footprint's largest semi-axis, seen square on
  double blur_px = 0;        // the disk this drop is seen through (0: none)
  double spread_px = 0;      // dispersion: red-blue shift
  double dispersion_levels = 0;
  bool dispersion = true;    // simulated
  double gravity_px = 0;     // gravity: shift against the spherical cap
  double gravity_levels = 0;
  bool gravity = true;       // simulated (the drop keeps its drawn elongation and flattening)
};

struct EffectPlan {
  bool dispersion_auto = false, gravity_auto = false, supersample_auto = false;
  std::vector<DropEffects> drops;  // in the order of SceneSample::drops, when dispersion or gravity is auto
  bool any_auto() const { return dispersion_auto || gravity_auto || supersample_auto; }
  // Dispersion is traced in this frame at all (some drop needs it, or it is not auto).
  bool dispersion_anywhere(const SceneConfig& config) const;
};

// `defocused`: the frame goes through the thin lens (renderer.cpp), whose circles of
// confusion then blur each drop; otherwise the paper's disk blur, if the scene has it.
EffectPlan plan_effects(const SceneConfig& config, const SceneSample& scene, const Camera& camera, bool defocused);

// The drops as rendered: the scene's, with gravity undone where the plan skips it.
std::vector<DropShape> rendered_shapes(const SceneSample& scene, const EffectPlan& plan);

// For the manifest: one line saying what was decided and why.
std::string dispersion_why(const EffectPlan& plan);
std::string gravity_why(const EffectPlan& plan);
std::string supersample_why(long long aliasing_pixels, long long smooth_pixels, int samples_per_pixel);

}  // namespace raindrop
