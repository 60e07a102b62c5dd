#pragma once
// Small fixtures shared by the unit tests.
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/common/error.h"
#include "raindrop/render/glass.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"

namespace raindrop::test {

inline constexpr double kDegToRad = M_PI / 180.0;

// Glass facing the camera (normal along +z) at distance n_cm.
inline GlassPlane upright_glass(double n_cm) { return GlassPlane{n_cm, M_PI / 2}; }

inline DropShape cap(double u, double v, double footprint, double tau_deg) {
  DropShape s;
  s.center = {u, v};
  s.footprint_radius = footprint;
  s.contact_angle = tau_deg * kDegToRad;
  return s;
}

// A scene with the thin-lens camera on (focused on the background unless the test moves it)
// and the paper's disk blur off, which a lens replaces.
inline SceneConfig lens_scene(DefocusMethod method = DefocusMethod::Layered) {
  SceneConfig c;
  c.blur.enabled = false;
  c.lens.enabled = true;
  c.lens.method = method;
  return c;
}

// A thin-lens sample without drops: upright glass at glass_cm, the background at background_cm,
// an f/f_number lens of focal_mm.
inline SceneSample lens_sample(double glass_cm, double f_number, double focal_mm, double background_cm) {
  SceneSample s;
  s.glass = upright_glass(glass_cm);
  s.background_distance_cm = background_cm;
  s.f_number = f_number;
  s.focal_length_mm = focal_mm;
  return s;
}

inline Camera camera(int w, int h, double f) {
  Camera c;
  c.fx = c.fy = f;
  c.cx = 0.5 * (w - 1);
  c.cy = 0.5 * (h - 1);
  c.width = w;
  c.height = h;
  return c;
}

// A scene file's text that parse_scene_json must refuse, with a one-line error naming `needle`.
inline void expect_scene_refused(const std::string& text, const std::string& needle) {
  try {
    parse_scene_json(text, "case.json");
    ADD_FAILURE() << "accepted: " << text;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
  }
}

inline std::vector<GeometryOptions> all_geometries() {
  return {GeometryOptions::parse("exact"), GeometryOptions::parse("mesh-256-smooth")};
}

// Test-name suffix for parameterised tests over geometries ("exact", "mesh_256_smooth").
inline std::string geometry_name(const ::testing::TestParamInfo<GeometryOptions>& info) {
  std::string name = info.param.describe();
  for (char& c : name) c = c == '-' ? '_' : c;
  return name;
}

inline std::vector<Drop> drops_of(const SceneSample& scene) {
  std::vector<Drop> drops;
  for (const DropShape& s : scene.drops) drops.emplace_back(s, scene.glass);
  return drops;
}

// A crowded glass: drops of every size with small gaps, so that many leaving rays pass near
// (and some meet) a neighbour.
inline SceneSample crowded_scene(std::uint64_t seed, const Camera& cam) {
  SceneConfig c = scene_preset("paper");
  c.drop_count = {400, 400};
  c.min_gap_cm = 0.0;
  c.contact_angle_deg = {60, 90};
  Rng rng(seed);
  return sample_scene(c, cam, rng);
}

// A scene to trace, and what a failure message calls it.
struct NamedScene {
  std::string name;
  SceneConfig config;
  SceneSample scene;
};

// Every preset's scene drawn with seeds 1 and 2 ("<preset> seed <n>").
inline std::vector<NamedScene> preset_scenes(const Camera& cam) {
  std::vector<NamedScene> scenes;
  for (const std::string& preset : scene_preset_names()) {
    for (std::uint64_t seed : {1, 2}) {
      Rng rng(seed);
      const SceneConfig c = scene_preset(preset);
      scenes.push_back({preset + " seed " + std::to_string(seed), c, sample_scene(c, cam, rng)});
    }
  }
  return scenes;
}

// A frame of uniform random 8-bit RGB noise of the camera's size, the same for every call:
// every pixel differs from its neighbours, so any change to a traced ray shows.
inline cv::Mat random_frame(const Camera& cam) {
  cv::Mat clean(cam.height, cam.width, CV_8UC3);
  cv::RNG(0x5eed).fill(clean, cv::RNG::UNIFORM, 0, 256);
  return clean;
}

// Same size, type and bytes.
inline bool equal_bits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

}  // namespace raindrop::test
