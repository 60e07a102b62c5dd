#pragma once
// What a scene asks for: parameter ranges of the imaging model and the effects to simulate.
// Loaded from a JSON scene file (see scenes/*.json and docs/SCENES.md); an effect that the
// file does not name is off, and an effect that is off is never built into the render.
//
// Units: lengths in centimetres on the glass and along the optical axis, angles in degrees
// in the file (radians inside), blur diameters in pixels at a 2048-pixel-wide frame.
#include <filesystem>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "raindrop/drop_accel.h"

namespace raindrop {

struct Range {
  double lo = 0, hi = 0;
};

enum class DropSizeParam { SphereRadius, FootprintRadius };
enum class BorderMode { Clamp, Mirror };
enum class BlurMethod { DiskSpan, DiskDirect, DiskAntialiased, Gaussian };
enum class TirMode { Black, Trace };

const char* to_string(BorderMode);
const char* to_string(BlurMethod);
const char* to_string(TirMode);

struct SceneConfig {
  std::string name = "paper";

  // Imaging model (paper section 3 ranges by default).
  Range glass_distance_cm{20, 40};        // N
  Range background_distance_cm{800, 1500};  // T
  Range tilt_deg{30, 45};                 // psi
  Range drop_count{50, 70};               // integers, inclusive
  DropSizeParam size_param = DropSizeParam::SphereRadius;
  Range drop_size_cm{0.8, 1.5};           // r (sphere) or a (footprint), per size_param
  Range contact_angle_deg{30, 45};        // tau
  double refractive_index = 1.333;
  bool allow_overlap = false;             // false: footprints never overlap (real drops merge)
  double min_gap_cm = 0.05;               // gap kept between footprints when !allow_overlap

  // Dark band: what a totally internally reflected ray shows. Black as in the paper, or
  // traced on through the drop (its escape into the car shows `interior_rgb`).
  TirMode tir = TirMode::Black;

  // Effects. The paper's: refraction and the dark band (always), blur. Beyond the paper:
  // fresnel, dispersion, gravity.
  struct Blur {
    bool enabled = true;
    Range diameter_px_2048{7, 20};  // disk diameter at 2048 px wide, scaled with the width
    BlurMethod method = BlurMethod::DiskSpan;
  } blur;
  struct Fresnel {
    bool enabled = false;
    glm::dvec3 interior_rgb{0.03, 0.03, 0.03};  // radiance reflected in from the car side
  } fresnel;
  struct Dispersion {
    bool enabled = false;
    glm::dvec3 wavelength_nm{620, 540, 460};  // where red, green, blue are traced
  } dispersion;
  struct Gravity {
    bool enabled = false;
    Range elongation{1.0, 1.3};  // downhill footprint stretch
    Range flattening{0.6, 1.0};  // height relative to the spherical cap
  } gravity;

  // Quality: the accuracy/time knobs.
  GeometryOptions geometry;
  int samples_per_pixel = 1;      // 1, 4, 16, 64 (square numbers: stratified grid)
  bool supersample_edges_only = true;
  BorderMode border = BorderMode::Mirror;

  // Effects that will run, in a fixed order, for the manifest and logs.
  std::vector<std::string> effect_names() const;
  glm::dvec3 channel_indices() const;  // refractive index per colour channel
};

// Built-in presets: "paper", "real-photo", "full-physics". Throws raindrop::Error otherwise.
SceneConfig scene_preset(const std::string& name);
std::vector<std::string> scene_preset_names();

// A preset name or a path to a JSON scene file. Throws raindrop::Error with a one-line
// message naming the file and the offending key.
SceneConfig load_scene(const std::string& name_or_path);
SceneConfig parse_scene_json(const std::string& text, const std::string& origin);

// The config as a JSON scene file (canonical: keys sorted, every field present); parsing it
// back gives the same config. Used for --print-scene and for the job fingerprint.
std::string scene_to_json(const SceneConfig& config);

}  // namespace raindrop
