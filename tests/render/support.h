#pragma once
// Small fixtures shared by the unit tests.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/common/error.h"
#include "raindrop/render/glass.h"
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

}  // namespace raindrop::test
