#include "raindrop/render/scene_config.h"

#include <cmath>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "raindrop/common/error.h"
#include "raindrop/render/optics.h"
#include "raindrop/render/trails.h"

namespace raindrop {
namespace {

using json = nlohmann::json;

// scenes/*.json, embedded at build time (see CMakeLists.txt) so that the presets and the
// files users copy from are the same text.
#include "scene_presets.inc"

class Reader {
 public:
  Reader(const json& j, std::string where, std::string origin)
      : j_(j), where_(std::move(where)), origin_(std::move(origin)) {
    if (!j_.is_object()) fail("must be a JSON object");
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw Error("scene " + origin_ + ": " + (where_.empty() ? "" : where_ + ": ") + what);
  }

  bool has(const std::string& key) {
    seen_.insert(key);
    return j_.contains(key);
  }

  bool holds_string(const std::string& key) const { return j_.contains(key) && j_.at(key).is_string(); }

  // Whether `key` holds the string "auto" (an effect left to the scene's physics, the same
  // as {"auto": true}).
  bool is_auto(const std::string& key) const {
    const json& v = j_.at(key);
    return v.is_string() && v.get<std::string>() == "auto";
  }

  // A number (fixed value) or [lo, hi] with lo <= hi, both inside [min, max].
  void range(const std::string& key, Range* out, double min, double max) {
    if (!has(key)) return;
    const json& v = j_.at(key);
    Range r;
    if (v.is_number()) {
      r.lo = r.hi = v.get<double>();
    } else if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number()) {
      r.lo = v[0].get<double>();
      r.hi = v[1].get<double>();
    } else {
      fail("'" + key + "' must be a number or [lo, hi]");
    }
    if (!(r.lo <= r.hi) || !(r.lo >= min) || !(r.hi <= max)) {
      std::ostringstream s;
      s << "'" << key << "' = [" << r.lo << ", " << r.hi << "] must satisfy " << min
        << " <= lo <= hi <= " << max;
      fail(s.str());
    }
    *out = r;
  }

  void number(const std::string& key, double* out, double min, double max) {
    Range r{*out, *out};
    range(key, &r, min, max);
    if (r.lo != r.hi) fail("'" + key + "' must be a single number");
    *out = r.lo;
  }

  void boolean(const std::string& key, bool* out) {
    if (!has(key)) return;
    if (!j_.at(key).is_boolean()) fail("'" + key + "' must be true or false");
    *out = j_.at(key).get<bool>();
  }

  std::string string(const std::string& key, const std::string& fallback) {
    if (!has(key)) return fallback;
    if (!j_.at(key).is_string()) fail("'" + key + "' must be a string");
    return j_.at(key).get<std::string>();
  }

  void vec3(const std::string& key, glm::dvec3* out, double min, double max) {
    if (!has(key)) return;
    const json& v = j_.at(key);
    if (!v.is_array() || v.size() != 3) fail("'" + key + "' must be [r, g, b]");
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number()) fail("'" + key + "' must be [r, g, b]");
      const double x = v[i].get<double>();
      if (!(x >= min && x <= max)) fail("'" + key + "' values must lie in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
      (*out)[i] = x;
    }
  }

  // [x, y], both inside [min, max].
  void vec2(const std::string& key, double* x, double* y, double min, double max) {
    if (!has(key)) return;
    const json& v = j_.at(key);
    if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number()) fail("'" + key + "' must be [x, y]");
    *x = v[0].get<double>();
    *y = v[1].get<double>();
    if (!(*x >= min && *x <= max && *y >= min && *y <= max))
      fail("'" + key + "' values must lie in [" + std::to_string(min) + ", " + std::to_string(max) + "]");
  }

  // A list of objects: one Reader per element ("key[i]" in messages).
  std::vector<Reader> elements(const std::string& key) {
    seen_.insert(key);
    const json& v = j_.at(key);
    if (!v.is_array()) fail("'" + key + "' must be a list of objects");
    std::vector<Reader> out;
    for (size_t i = 0; i < v.size(); ++i)
      out.emplace_back(v[i], (where_.empty() ? "" : where_ + ".") + key + "[" + std::to_string(i) + "]", origin_);
    return out;
  }

  Reader child(const std::string& key) {
    seen_.insert(key);
    return Reader(j_.at(key), where_.empty() ? key : where_ + "." + key, origin_);
  }

  // Unknown keys are errors: a misspelt effect must not silently turn into "effect off".
  void reject_unknown() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (!seen_.count(it.key())) fail("unknown key '" + it.key() + "'");
    }
  }

 private:
  const json& j_;
  std::string where_, origin_;
  std::set<std::string> seen_;
};

template <class Enum>
Enum parse_enum(Reader& r, const std::string& key, Enum fallback,
                const std::map<std::string, Enum>& names) {
  const std::string text = r.string(key, "");
  if (text.empty()) return fallback;
  const auto it = names.find(text);
  if (it == names.end()) {
    std::string options;
    for (const auto& [name, value] : names) options += (options.empty() ? "" : ", ") + name;
    r.fail("'" + key + "' = '" + text + "' is not one of: " + options);
  }
  return it->second;
}

}  // namespace

const char* to_string(BorderMode m) { return m == BorderMode::Clamp ? "clamp" : "mirror"; }
const char* to_string(TirMode m) { return m == TirMode::Black ? "black" : "trace"; }
const char* to_string(SizeDistribution d) { return d == SizeDistribution::Uniform ? "uniform" : "log-uniform"; }
const char* to_string(DefocusMethod m) {
  switch (m) {
    case DefocusMethod::Layered: return "layered";
    case DefocusMethod::LayeredExact: return "layered-exact";
    case DefocusMethod::Aperture: return "aperture";
  }
  return "?";
}
const char* to_string(Supersample s) {
  return s == Supersample::Edges ? "edges" : (s == Supersample::All ? "all" : "auto");
}
const char* to_string(BlurMethod m) {
  switch (m) {
    case BlurMethod::DiskSpan: return "disk";
    case BlurMethod::DiskDirect: return "disk-direct";
    case BlurMethod::DiskAntialiased: return "disk-aa";
    case BlurMethod::Gaussian: return "gaussian";
  }
  return "?";
}

std::vector<std::string> SceneConfig::effect_names() const {
  std::vector<std::string> names{"refraction", tir == TirMode::Black ? "dark_band" : "internal_reflection"};
  if (blur.enabled) names.push_back("blur");
  if (lens.enabled) names.push_back(std::string("defocus-") + to_string(lens.method));
  if (sky.enabled) names.push_back("sky");
  if (fresnel.enabled) names.push_back("fresnel");
  if (dispersion.enabled) names.push_back(dispersion.automatic ? "dispersion-auto" : "dispersion");
  if (gravity.enabled) names.push_back(gravity.automatic ? "gravity-auto" : "gravity");
  if (outline.enabled) names.push_back("outline");
  if (trails.enabled) names.push_back("trails");
  if (highlights.enabled) names.push_back("highlights");
  if (veil.enabled) names.push_back("veil");
  if (sensor.enabled) names.push_back("sensor");
  return names;
}

glm::dvec3 SceneConfig::channel_indices() const {
  if (!dispersion.enabled) return glm::dvec3(refractive_index);
  // Keep the configured index at the D line and add water's dispersion around it.
  const double shift = refractive_index - water_index(0.5893);
  glm::dvec3 n;
  for (int c = 0; c < 3; ++c) n[c] = water_index(dispersion.wavelength_nm[c] / 1000.0) + shift;
  return n;
}

SceneConfig parse_scene_json(const std::string& text, const std::string& origin, const std::string& default_name) {
  json j;
  // A key given twice in one object: JSON keeps the last, which would drop the first's
  // settings without a word ("effects" twice ran without the first one's blur). Refused.
  std::vector<std::set<std::string>> keys_of_open_objects;
  std::string twice;
  const json::parser_callback_t refuse_repeated_keys = [&](int, json::parse_event_t event, json& parsed) {
    if (event == json::parse_event_t::object_start) {
      keys_of_open_objects.emplace_back();
    } else if (event == json::parse_event_t::object_end) {
      keys_of_open_objects.pop_back();
    } else if (event == json::parse_event_t::key && twice.empty() &&
               !keys_of_open_objects.back().insert(parsed.get<std::string>()).second) {
      twice = parsed.get<std::string>();
    }
    return true;
  };
  try {
    j = json::parse(text, refuse_repeated_keys, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const json::exception& e) {
    // Not only parse_error: a number too large for a double (1e309) is an out_of_range.
    throw Error("scene " + origin + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  if (!twice.empty()) throw Error("scene " + origin + ": '" + twice + "' is given twice in one object");
  Reader r(j, "", origin);
  SceneConfig c;
  c.name = r.string("name", default_name.empty() ? std::filesystem::path(origin).stem().string() : default_name);
  r.range("glass_distance_cm", &c.glass_distance_cm, 1, 1000);
  r.range("background_distance_cm", &c.background_distance_cm, 10, 1e6);
  r.range("tilt_deg", &c.tilt_deg, 15, 90);
  r.range("drop_count", &c.drop_count, 0, kMaxDropCount);
  if (c.drop_count.lo != std::floor(c.drop_count.lo) || c.drop_count.hi != std::floor(c.drop_count.hi))
    r.fail("'drop_count' must be whole numbers");
  const bool sphere = r.has("sphere_radius_cm"), footprint = r.has("footprint_radius_cm");
  if (sphere && footprint) r.fail("give either 'sphere_radius_cm' or 'footprint_radius_cm', not both");
  if (footprint) {
    c.size_param = DropSizeParam::FootprintRadius;
    r.range("footprint_radius_cm", &c.drop_size_cm, 1e-3, 50);
  } else {
    r.range("sphere_radius_cm", &c.drop_size_cm, 1e-3, 50);
  }
  c.size_distribution = parse_enum<SizeDistribution>(
      r, "size_distribution", c.size_distribution,
      {{"uniform", SizeDistribution::Uniform}, {"log-uniform", SizeDistribution::LogUniform}});
  r.range("contact_angle_deg", &c.contact_angle_deg, 1, 90);
  r.number("refractive_index", &c.refractive_index, 1.0, 3.0);
  r.boolean("allow_overlap", &c.allow_overlap);
  r.number("min_gap_cm", &c.min_gap_cm, 0, 10);
  r.boolean("coalesce", &c.coalesce);
  if (c.coalesce && !c.allow_overlap)
    r.fail("'coalesce' merges drops whose footprints overlap: it needs \"allow_overlap\": true");
  c.tir = parse_enum<TirMode>(r, "dark_band", c.tir, {{"black", TirMode::Black}, {"trace", TirMode::Trace}});
  if (r.has("drops")) {
    for (Reader d : r.elements("drops")) {
      PlacedDrop p;
      const bool px = d.has("center_px"), cm = d.has("center_cm");
      if (px == cm) d.fail("give the centre as either 'center_px' [x, y] or 'center_cm' [u, v]");
      p.at_pixel = px;
      if (px) d.vec2("center_px", &p.x, &p.y, -1e5, 1e5);
      else d.vec2("center_cm", &p.x, &p.y, -1e4, 1e4);
      const bool sph = d.has("sphere_radius_cm"), fp = d.has("footprint_radius_cm");
      if (sph == fp) d.fail("give the size as either 'sphere_radius_cm' or 'footprint_radius_cm'");
      p.size_param = fp ? DropSizeParam::FootprintRadius : DropSizeParam::SphereRadius;
      d.number(fp ? "footprint_radius_cm" : "sphere_radius_cm", &p.size_cm, 1e-3, 50);
      if (!d.has("contact_angle_deg")) d.fail("'contact_angle_deg' is required");
      d.number("contact_angle_deg", &p.contact_angle_deg, 1, 90);
      d.reject_unknown();
      c.drops.push_back(p);
    }
    if (c.drops.size() + static_cast<size_t>(c.drop_count.hi) > static_cast<size_t>(kMaxDropCount))
      r.fail("'drops' lists " + std::to_string(c.drops.size()) + " drops beside up to " +
             std::to_string(static_cast<int>(c.drop_count.hi)) + " random ones ('drop_count'): more than " +
             std::to_string(kMaxDropCount) + " in all");
  }

  if (r.has("camera")) {
    Reader l = r.child("camera");
    c.lens.enabled = true;
    l.range("f_number", &c.lens.f_number, 0.5, 1e6);
    l.range("focal_length_mm", &c.lens.focal_length_mm, 0.5, 2000);
    c.lens.method = parse_enum<DefocusMethod>(l, "defocus", c.lens.method,
                                              {{"layered", DefocusMethod::Layered},
                                               {"layered-exact", DefocusMethod::LayeredExact},
                                               {"aperture", DefocusMethod::Aperture}});
    double samples = c.lens.aperture_samples;
    l.number("aperture_samples", &samples, 1, 1024);
    const int side = static_cast<int>(std::lround(std::sqrt(samples)));
    if (side * side != samples) l.fail("'aperture_samples' must be a square number (1, 4, 16, 64, 256)");
    c.lens.aperture_samples = static_cast<int>(samples);
    l.number("mask_threshold", &c.lens.mask_threshold, 1e-3, 1);
    if (l.has("drops_in_focus")) {
      const std::string in_focus = l.string("drops_in_focus", "aperture");
      if (in_focus == "aperture") c.lens.trace_in_focus = true;
      else if (in_focus == "centre") c.lens.trace_in_focus = false;
      else l.fail("'drops_in_focus' must be \"aperture\" or \"centre\"");
    }
    // "background" (the default), "glass", or a distance in cm ([lo, hi] drawn per sample).
    if (l.holds_string("focus_distance_cm")) {
      const std::string focus = l.string("focus_distance_cm", "background");
      if (focus == "background") c.lens.focus = SceneConfig::Focus::Background;
      else if (focus == "glass") c.lens.focus = SceneConfig::Focus::Glass;
      else l.fail("'focus_distance_cm' must be \"background\", \"glass\", a distance in cm or [lo, hi]");
    } else if (l.has("focus_distance_cm")) {
      l.range("focus_distance_cm", &c.lens.focus_distance_cm, 1, 1e7);
      c.lens.focus = SceneConfig::Focus::Distance;
    }
    l.reject_unknown();
  }

  // Effects: present = on; dispersion and gravity may be "auto" (or carry "auto": true).
  c.blur.enabled = c.fresnel.enabled = c.dispersion.enabled = c.gravity.enabled = c.sky.enabled = false;
  c.sensor.enabled = c.highlights.enabled = c.veil.enabled = c.outline.enabled = c.trails.enabled = false;
  if (r.has("effects")) {
    Reader e = r.child("effects");
    for (const char* fixed : {"blur", "sky", "fresnel", "highlights", "veil", "sensor", "outline", "trails"}) {
      if (e.has(fixed) && e.is_auto(fixed))
        e.fail(std::string("'") + fixed + "' has no \"auto\" (only dispersion, gravity and quality.supersample do)");
    }
    if (e.has("blur")) {
      Reader b = e.child("blur");
      c.blur.enabled = true;
      b.range("diameter_px_2048", &c.blur.diameter_px_2048, 0, 200);
      c.blur.method = parse_enum<BlurMethod>(b, "method", c.blur.method,
                                             {{"disk", BlurMethod::DiskSpan},
                                              {"disk-direct", BlurMethod::DiskDirect},
                                              {"disk-aa", BlurMethod::DiskAntialiased},
                                              {"gaussian", BlurMethod::Gaussian}});
      b.reject_unknown();
    }
    if (e.has("sky")) {
      Reader k = e.child("sky");
      c.sky.enabled = true;
      k.number("fade_rows", &c.sky.fade_rows, 0, 10);
      k.number("gain", &c.sky.gain, 0, 10);
      k.reject_unknown();
    }
    if (e.has("highlights")) {
      Reader h = e.child("highlights");
      c.highlights.enabled = true;
      // Below 0.5 of full scale nothing is clipped; a gain under 1 would darken highlights.
      h.number("threshold", &c.highlights.threshold, 0.5, 0.999);
      h.range("gain", &c.highlights.gain, 1, 1000);
      h.reject_unknown();
    }
    if (e.has("sensor")) {
      Reader n = e.child("sensor");
      c.sensor.enabled = true;
      n.range("noise_levels", &c.sensor.noise_levels, 0, 50);
      n.range("jpeg_quality", &c.sensor.jpeg_quality, 0, 100);
      if (c.sensor.jpeg_quality.hi > 0 && c.sensor.jpeg_quality.lo < 1)
        n.fail("'jpeg_quality' is [0, 0] (not compressed) or a range within 1-100");
      if (c.sensor.jpeg_quality.lo != std::floor(c.sensor.jpeg_quality.lo) ||
          c.sensor.jpeg_quality.hi != std::floor(c.sensor.jpeg_quality.hi))
        n.fail("'jpeg_quality' takes whole numbers");
      n.reject_unknown();
    }
    if (e.has("veil")) {
      Reader v = e.child("veil");
      c.veil.enabled = true;
      // Depth 3 scatters 95% of the light (fog on the glass); a lobe needs some width.
      v.range("optical_depth", &c.veil.optical_depth, 0, 3);
      v.range("spread_deg", &c.veil.spread_deg, 0.1, 45);
      v.reject_unknown();
    }
    if (e.has("outline")) {
      Reader o = e.child("outline");
      c.outline.enabled = true;
      // Beyond 0.9 the contact line would nearly reach the drop's centre.
      o.range("peak_deviation", &c.outline.peak_deviation, 0, 0.9);
      double modes = c.outline.modes;
      o.number("modes", &modes, 2, kMaxOutlineModes);
      if (modes != std::floor(modes)) o.fail("'modes' takes a whole number");
      c.outline.modes = static_cast<int>(modes);
      o.reject_unknown();
    }
    if (e.has("trails")) {
      Reader t = e.child("trails");
      c.trails.enabled = true;
      // cos(receding) - cos(advancing) lies in [0, 2]; caps finer than 2% of their drop, or
      // closer than 0.3 of their radii (piles), only cost time.
      t.range("hysteresis", &c.trails.hysteresis, 0, 2);
      t.range("length_radii", &c.trails.length_radii, 0, 50);
      t.range("width", &c.trails.width, 0.02, 1);
      t.range("contact_angle_deg", &c.trails.contact_angle_deg, 1, 90);
      t.range("spacing", &c.trails.spacing, 0.3, 3);
      t.number("max_volume_fraction", &c.trails.max_volume_fraction, 0, 0.9);
      t.reject_unknown();
    }
    if (e.has("fresnel")) {
      Reader f = e.child("fresnel");
      c.fresnel.enabled = true;
      f.vec3("interior_rgb", &c.fresnel.interior_rgb, 0, 1);
      f.reject_unknown();
    }
    // Dispersion and gravity: "auto", or their object, where "auto": true says the same.
    auto may_be_auto = [&](const char* key, bool* enabled, bool* automatic, const std::function<void(Reader&)>& read) {
      if (!e.has(key)) return;
      *enabled = true;
      if (e.is_auto(key)) {
        *automatic = true;
        return;
      }
      Reader sub = e.child(key);
      sub.boolean("auto", automatic);
      read(sub);
      sub.reject_unknown();
    };
    may_be_auto("dispersion", &c.dispersion.enabled, &c.dispersion.automatic,
                [&](Reader& d) { d.vec3("wavelength_nm", &c.dispersion.wavelength_nm, 380, 780); });
    may_be_auto("gravity", &c.gravity.enabled, &c.gravity.automatic, [&](Reader& g) {
      g.range("elongation", &c.gravity.elongation, 1, 3);
      g.range("flattening", &c.gravity.flattening, 0.1, 1);
    });
    e.reject_unknown();
  }

  if (c.lens.enabled && c.blur.enabled)
    r.fail("a scene with a 'camera' is defocused by its lens: remove 'effects.blur' (the paper's disk blur)");
  if (c.highlights.enabled && !c.lens.enabled)
    r.fail("'effects.highlights' lifts the light a lens spreads: it needs a 'camera' section");

  if (r.has("quality")) {
    Reader q = r.child("quality");
    try {
      c.geometry = GeometryOptions::parse(q.string("geometry", "exact"));
    } catch (const Error& e) {
      q.fail(e.what());  // with the file's name
    }
    // Each trail cap is a drop of the mesh too: up to kMaxTrailCaps per drop (a scene that
    // passed without them took 6 to 23 GB).
    // A trail's caps are at least 2 spacing x width drop radii apart (trails.h), within its
    // length: at most 1 + length / (2 spacing width) of them, and kMaxTrailCaps.
    const double drops = c.drop_count.hi + static_cast<double>(c.drops.size());
    const double caps = std::min<double>(kMaxTrailCaps, 1 + std::floor(c.trails.length_radii.hi /
                                                                     (2 * c.trails.spacing.lo * c.trails.width.lo)));
    const double shapes = drops * (c.trails.enabled ? 1 + caps : 1);
    const double mesh_bytes = c.geometry.mesh_bytes_per_drop() * shapes;
    if (mesh_bytes > kMaxMeshBytes) {
      std::ostringstream m;
      m << std::fixed << std::setprecision(1) << "'geometry' = '" << c.geometry.describe() << "' with up to "
        << static_cast<long long>(drops) << " drops"
        << (c.trails.enabled ? " and their trails' caps (up to " + std::to_string(static_cast<int>(caps)) + " a drop)" : "")
        << " takes about " << mesh_bytes / (1 << 30) << " GB of mesh a sample, more than the "
        << kMaxMeshBytes / (1 << 30) << " GB limit; use fewer segments or drops";
      q.fail(m.str());
    }
    double spp = c.samples_per_pixel;
    q.number("samples_per_pixel", &spp, 1, 256);
    const int side = static_cast<int>(std::lround(std::sqrt(spp)));
    if (side * side != spp) q.fail("'samples_per_pixel' must be a square number (1, 4, 9, 16, ...)");
    c.samples_per_pixel = static_cast<int>(spp);
    c.supersample = parse_enum<Supersample>(q, "supersample", c.supersample,
                                            {{"edges", Supersample::Edges}, {"all", Supersample::All}, {"auto", Supersample::Auto}});
    c.border = parse_enum<BorderMode>(q, "border", c.border,
                                      {{"clamp", BorderMode::Clamp}, {"mirror", BorderMode::Mirror}});
    q.reject_unknown();
  }
  r.reject_unknown();
  return c;
}

std::string scene_to_json(const SceneConfig& c) {
  auto range = [](const Range& r) { return json::array({r.lo, r.hi}); };
  auto vec3 = [](const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); };
  json j;
  j["name"] = c.name;
  j["glass_distance_cm"] = range(c.glass_distance_cm);
  j["background_distance_cm"] = range(c.background_distance_cm);
  j["tilt_deg"] = range(c.tilt_deg);
  j["drop_count"] = range(c.drop_count);
  j[c.size_param == DropSizeParam::SphereRadius ? "sphere_radius_cm" : "footprint_radius_cm"] = range(c.drop_size_cm);
  if (c.size_distribution != SizeDistribution::Uniform) j["size_distribution"] = to_string(c.size_distribution);
  j["contact_angle_deg"] = range(c.contact_angle_deg);
  if (c.lens.enabled)
    j["camera"] = {{"f_number", range(c.lens.f_number)},
                   {"focal_length_mm", range(c.lens.focal_length_mm)},
                   {"defocus", to_string(c.lens.method)},
                   {"aperture_samples", c.lens.aperture_samples},
                   {"drops_in_focus", c.lens.trace_in_focus ? "aperture" : "centre"},
                   {"mask_threshold", c.lens.mask_threshold}};
  // Only where the focus is off the background, so that a scene focused on it prints (and
  // fingerprints its jobs) as it always did.
  if (c.lens.enabled && c.lens.focus != SceneConfig::Focus::Background)
    j["camera"]["focus_distance_cm"] =
        c.lens.focus == SceneConfig::Focus::Glass ? json("glass") : range(c.lens.focus_distance_cm);
  j["refractive_index"] = c.refractive_index;
  j["allow_overlap"] = c.allow_overlap;
  j["min_gap_cm"] = c.min_gap_cm;
  j["coalesce"] = c.coalesce;
  j["dark_band"] = to_string(c.tir);
  if (!c.drops.empty()) {
    json drops = json::array();
    for (const PlacedDrop& p : c.drops)
      drops.push_back({{p.at_pixel ? "center_px" : "center_cm", json::array({p.x, p.y})},
                       {p.size_param == DropSizeParam::FootprintRadius ? "footprint_radius_cm" : "sphere_radius_cm", p.size_cm},
                       {"contact_angle_deg", p.contact_angle_deg}});
    j["drops"] = drops;
  }
  json effects = json::object();
  if (c.blur.enabled) effects["blur"] = {{"diameter_px_2048", range(c.blur.diameter_px_2048)}, {"method", to_string(c.blur.method)}};
  if (c.sky.enabled) effects["sky"] = {{"fade_rows", c.sky.fade_rows}, {"gain", c.sky.gain}};
  if (c.fresnel.enabled) effects["fresnel"] = {{"interior_rgb", vec3(c.fresnel.interior_rgb)}};
  // "auto" only where it is on, so that a scene without it prints as it always did.
  if (c.dispersion.enabled) {
    effects["dispersion"] = {{"wavelength_nm", vec3(c.dispersion.wavelength_nm)}};
    if (c.dispersion.automatic) effects["dispersion"]["auto"] = true;
  }
  if (c.gravity.enabled) {
    effects["gravity"] = {{"elongation", range(c.gravity.elongation)}, {"flattening", range(c.gravity.flattening)}};
    if (c.gravity.automatic) effects["gravity"]["auto"] = true;
  }
  if (c.outline.enabled)
    effects["outline"] = {{"peak_deviation", range(c.outline.peak_deviation)}, {"modes", c.outline.modes}};
  if (c.trails.enabled)
    effects["trails"] = {{"hysteresis", range(c.trails.hysteresis)},
                         {"length_radii", range(c.trails.length_radii)},
                         {"width", range(c.trails.width)},
                         {"contact_angle_deg", range(c.trails.contact_angle_deg)},
                         {"spacing", range(c.trails.spacing)},
                         {"max_volume_fraction", c.trails.max_volume_fraction}};
  if (c.highlights.enabled)
    effects["highlights"] = {{"threshold", c.highlights.threshold}, {"gain", range(c.highlights.gain)}};
  if (c.veil.enabled)
    effects["veil"] = {{"optical_depth", range(c.veil.optical_depth)}, {"spread_deg", range(c.veil.spread_deg)}};
  if (c.sensor.enabled)
    effects["sensor"] = {{"noise_levels", range(c.sensor.noise_levels)}, {"jpeg_quality", range(c.sensor.jpeg_quality)}};
  j["effects"] = effects;
  j["quality"] = {{"geometry", c.geometry.describe()},
                  {"samples_per_pixel", c.samples_per_pixel},
                  {"supersample", to_string(c.supersample)},
                  {"border", to_string(c.border)}};
  return j.dump(2);
}

std::vector<std::string> scene_preset_names() {
  std::vector<std::string> names;
  for (const auto& p : kScenePresets) names.emplace_back(p.name);
  return names;
}

SceneConfig scene_preset(const std::string& name) {
  for (const auto& p : kScenePresets) {
    if (name == p.name) return parse_scene_json(p.json, "preset '" + name + "'");
  }
  std::string all;
  for (const auto& n : scene_preset_names()) all += (all.empty() ? "" : ", ") + n;
  throw Error("no scene preset '" + name + "' (presets: " + all + ")");
}

SceneConfig load_scene(const std::string& name_or_path) {
  for (const auto& p : kScenePresets) {
    if (name_or_path == p.name) return scene_preset(name_or_path);
  }
  std::ifstream in(name_or_path, std::ios::binary);
  if (!in) throw Error("scene file '" + name_or_path + "' cannot be read (and is not a preset: " + [] {
                         std::string all;
                         for (const auto& n : scene_preset_names()) all += (all.empty() ? "" : ", ") + n;
                         return all;
                       }() + ")");
  std::stringstream s;
  s << in.rdbuf();
  // Named after the file, not after the quoted origin of the messages: "'all.json'" gave "'all".
  return parse_scene_json(s.str(), "'" + name_or_path + "'", std::filesystem::path(name_or_path).stem().string());
}

}  // namespace raindrop
