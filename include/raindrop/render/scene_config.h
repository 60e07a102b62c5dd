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

#include "raindrop/render/drop_accel.h"

namespace raindrop {

struct Range {
  double lo = 0, hi = 0;
};

enum class DropSizeParam { SphereRadius, FootprintRadius };
enum class BorderMode { Clamp, Mirror };
enum class BlurMethod { DiskSpan, DiskDirect, DiskAntialiased, Gaussian };
enum class TirMode { Black, Trace };
enum class SizeDistribution { Uniform, LogUniform };
// How a thin-lens camera's defocus of the drops is rendered (see defocus.h; the aperture
// reference is tracer.h's trace_aperture). LayeredExact: the layered sums with one dense
// cv::filter2D per drop, kept to compare the fast path against.
enum class DefocusMethod { Layered, LayeredExact, Aperture };
// Which drop pixels get samples_per_pixel > 1: those on an edge (next to another drop, the
// background or the dark band), every drop pixel, or (auto) the edges and the inside pixels
// whose single sample aliases (effect_policy.h).
enum class Supersample { Edges, All, Auto };

const char* to_string(BorderMode);
const char* to_string(BlurMethod);
const char* to_string(TirMode);
const char* to_string(SizeDistribution);
const char* to_string(DefocusMethod);
const char* to_string(Supersample);

// The most drops a scene may ask for per sample. The presets ask for at most 300 and 1000
// small drops already crowd a frame; placing each drop tests up to 200 positions against every
// drop placed before it, and a mesh's memory grows with the count (drop_accel.h), so 5000 drops
// made placement and rendering slow for no use.
inline constexpr int kMaxDropCount = 1000;

// A drop the scene file places itself (`drops`), for tests and for users who want one drop
// where they say: its footprint centre, as the pixel of the output frame where the camera sees
// it or as a point on the glass, its size and its contact angle.
struct PlacedDrop {
  bool at_pixel = true;     // centre: a pixel (x right, y down) of the output frame, else glass
  double x = 0, y = 0;      // px, or cm on the glass (u across, v downhill from the optical axis)
  DropSizeParam size_param = DropSizeParam::FootprintRadius;
  double size_cm = 0.5;     // a or r, per size_param
  double contact_angle_deg = 40;
};

struct SceneConfig {
  std::string name = "paper";

  // Imaging model (paper section 3 ranges by default).
  Range glass_distance_cm{20, 40};        // N
  Range background_distance_cm{800, 1500};  // T
  Range tilt_deg{30, 45};                 // psi
  Range drop_count{50, 70};               // integers, inclusive
  DropSizeParam size_param = DropSizeParam::SphereRadius;
  Range drop_size_cm{0.8, 1.5};           // r (sphere) or a (footprint), per size_param
  // Uniform as in the paper; log-uniform gives many small drops and few large ones, as on
  // real glass.
  SizeDistribution size_distribution = SizeDistribution::Uniform;
  Range contact_angle_deg{30, 45};        // tau
  double refractive_index = 1.333;
  bool allow_overlap = false;             // false: footprints never overlap (real drops merge)
  double min_gap_cm = 0.05;               // gap kept between footprints when !allow_overlap
  bool coalesce = false;                  // with allow_overlap: overlapping drops merge into one (coalesce.h)
  // Placed first, exactly as given (they may touch each other); the drop_count random drops
  // then keep clear of them as of each other.
  std::vector<PlacedDrop> drops;

  // Dark band: what a totally internally reflected ray shows. Black as in the paper, or
  // traced on through the drop (its escape into the car shows `interior_rgb`).
  TirMode tir = TirMode::Black;

  // Effects. The paper's: refraction and the dark band (always), blur. Beyond the paper:
  // fresnel, dispersion, gravity. Dispersion and gravity may be `automatic` ("auto" in the
  // file): simulated for the drops where the scene's physics makes them perceptible at the
  // output resolution, skipped for the others (effect_policy.h).
  struct Blur {
    bool enabled = true;
    Range diameter_px_2048{7, 20};  // disk diameter at 2048 px wide, scaled with the width
    BlurMethod method = BlurMethod::DiskAntialiased;  // as docs/SCENES.md says, and the presets name
  } blur;
  struct Fresnel {
    bool enabled = false;
    glm::dvec3 interior_rgb{0.03, 0.03, 0.03};  // radiance reflected in from the car side
  } fresnel;
  struct Dispersion {
    bool enabled = false;
    bool automatic = false;
    glm::dvec3 wavelength_nm{620, 540, 460};  // where red, green, blue are traced
  } dispersion;
  struct Gravity {
    bool enabled = false;
    bool automatic = false;  // the shapes are still drawn for every drop, then kept or not
    Range elongation{1.0, 1.3};  // downhill footprint stretch
    Range flattening{0.6, 1.0};  // height relative to the spherical cap
  } gravity;

  // Irregular contact lines (outline.h): each drop's rim strays from its circle by a peak
  // fraction drawn per drop from `peak_deviation`, over Fourier modes 2..`modes`; footprint
  // area is kept. Drawn after every other draw of the sample.
  struct Outline {
    bool enabled = false;
    Range peak_deviation{0.0, 0.3};
    int modes = 6;
  } outline;

  // Trails (trails.h): a drop too heavy for the glass to hold has slid downhill and left a
  // streak of water behind it, a row of small flat caps that join into a film where `spacing`
  // is below 1. Which drops slide follows from their size, the glass' slope and the contact
  // angle hysteresis drawn per drop (Furmidge's balance); each gives its trail the water it
  // holds. Drawn after every other draw of the sample, outlines included.
  struct Trails {
    bool enabled = false;
    Range hysteresis{0.1, 0.4};        // cos(receding angle) - cos(advancing angle), per drop
    Range length_radii{2, 8};          // how far the drop slid, in its footprint radii
    Range width{0.15, 0.3};            // a trail cap's footprint radius / the drop's
    Range contact_angle_deg{10, 25};   // the trail's caps: a thin film
    Range spacing{0.7, 1.3};           // centre distance / the sum of two neighbours' radii
    double max_volume_fraction = 0.5;  // the most of its water a drop leaves behind
  } trails;

  // A thin-lens camera (optional). Without it the camera is a pinhole and the drops get the
  // paper's disk blur (effects.blur). With it, drops are defocused as a real lens focused on
  // the street sees them: each drop spreads over its circle of confusion and becomes
  // semi-transparent where it is smaller than that circle. The lens' aperture in cm is
  // focal_length / f_number; the circle of confusion of a point at depth z, with focus on
  // the background at S, is aperture * fx_px * |1/z - 1/S| pixels. `focus` may move the plane
  // of focus off the background: onto the glass (a phone held to a rained-on window, which
  // focuses on the drops), or to a drawn distance; the street is then defocused too
  // (background_defocus.h).
  enum class Focus { Background, Glass, Distance };
  struct Lens {
    bool enabled = false;
    Focus focus = Focus::Background;
    Range focus_distance_cm{0, 0};  // with Focus::Distance: drawn per sample, after every other draw
    Range f_number{2, 8};
    Range focal_length_mm{5, 5};  // physical focal length (Cityscapes: fx 2262 px x 2.2 um ~ 5 mm)
    DefocusMethod method = DefocusMethod::Layered;
    int aperture_samples = 16;    // per pixel, for method Aperture and for drops in focus (square number)
    // The layered path's drops in focus (circles under half a pixel): traced through the
    // aperture where it shows (true), or through the lens' centre alone (false: faster, and
    // farther from the reference inside them; defocus.h, traced_through_aperture).
    bool trace_in_focus = true;
    double mask_threshold = 0.1;  // binary mask = coverage >= this
  } lens;

  // What refracted rays see above the frame: the sky (its colour estimated from the brightest
  // part of the frame's top third) instead of a mirrored copy of the frame. A drop is a
  // wide-angle lens whose lower half looks up into the sky: this is why real drops are bright.
  struct Sky {
    bool enabled = false;
    double fade_rows = 0.15;  // fraction of the frame height over which the mirror fades into the sky
    double gain = 1.0;        // sky radiance relative to the estimate (overcast ~1, sunny >1)
  } sky;

  // Clipped highlights lifted back to a brighter linear value before the lens spreads them
  // (highlights.h), with a thin-lens camera only: the brightest channel above `threshold`
  // (a fraction of full scale, as stored) is scaled up to `gain` at full scale, the gain drawn
  // per sample. A frame with no pixel at or above the threshold skips it.
  struct Highlights {
    bool enabled = false;
    double threshold = 0.9;
    Range gain{4, 16};
  } highlights;

  // What the camera adds after the optics, to the rainy image only (sensor.h): Gaussian noise
  // of a sigma drawn per sample (levels of 8 bits), then JPEG at a quality drawn per sample
  // ([0, 0]: not compressed).
  struct Sensor {
    bool enabled = false;
    Range noise_levels{1, 3};
    Range jpeg_quality{0, 0};
  } sensor;

  // The veil of wet glass (veil.h): a scattering layer of optical depth `optical_depth` (its
  // thickness times its scattering coefficient; s = 1 - exp(-depth) of the light is scattered)
  // spreads light over a lobe of angular standard deviation `spread_deg`, on the rainy image
  // only. Both drawn per sample.
  struct Veil {
    bool enabled = false;
    Range optical_depth{0.01, 0.03};
    Range spread_deg{2, 10};
  } veil;

  // Quality: the accuracy/time knobs.
  GeometryOptions geometry;
  int samples_per_pixel = 1;      // 1, 4, 16, 64 (square numbers: stratified grid)
  Supersample supersample = Supersample::Edges;
  BorderMode border = BorderMode::Mirror;

  // Effects that will run, in a fixed order, for the manifest and logs.
  std::vector<std::string> effect_names() const;
  glm::dvec3 channel_indices() const;  // refractive index per colour channel
  // Whether no two drops' caps can meet (DropAccel::set_disjoint): footprints kept apart mean
  // caps kept apart (a cap never reaches past its footprint for contact angles up to 90
  // degrees); a trail overlaps its drop.
  bool drops_disjoint() const { return !allow_overlap && !trails.enabled; }
};

// Built-in presets: "paper", "real-photo", "full-physics". Throws raindrop::Error otherwise.
SceneConfig scene_preset(const std::string& name);
std::vector<std::string> scene_preset_names();

// A preset name or a path to a JSON scene file. Throws raindrop::Error with a one-line
// message naming the file and the offending key.
SceneConfig load_scene(const std::string& name_or_path);
// `origin` names the text in messages; `default_name` is the scene's name where the text gives
// none (empty: the stem of `origin`).
SceneConfig parse_scene_json(const std::string& text, const std::string& origin, const std::string& default_name = "");

// The config as a JSON scene file (canonical: keys sorted, every field present); parsing it
// back gives the same config. Used for --print-scene and for the job fingerprint.
std::string scene_to_json(const SceneConfig& config);

}  // namespace raindrop
