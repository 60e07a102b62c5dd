#pragma once
// The windshield: an infinite plane through (0, 0, N) tilted by psi from the ground. Its
// thickness and its own refraction are ignored, as in the paper.
//
// Frame on the glass: `across` is horizontal (camera x), `downhill` points down the slope
// (the direction a drop would run), `normal` points away from the camera, towards the
// outside where the drops sit. With gravity along camera +y these are
//   normal   = (0, -cos psi, sin psi)
//   downhill = (0,  sin psi, cos psi)
#include <cmath>
#include <optional>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace raindrop {

struct GlassPlane {
  double distance = 30;  // N, cm along the optical axis
  double tilt = 0.6;     // psi, radians from the ground; pi/2 = upright, facing the camera

  glm::dvec3 origin() const { return {0, 0, distance}; }
  glm::dvec3 normal() const { return {0, -std::cos(tilt), std::sin(tilt)}; }
  glm::dvec3 across() const { return {1, 0, 0}; }
  glm::dvec3 downhill() const { return {0, std::sin(tilt), std::cos(tilt)}; }

  // Camera-space point of glass coordinates (u across, v downhill), in cm.
  glm::dvec3 point(const glm::dvec2& uv) const {
    return origin() + uv.x * across() + uv.y * downhill();
  }
  // Glass coordinates of a camera-space point (projected onto the plane).
  glm::dvec2 coords(const glm::dvec3& p) const {
    const glm::dvec3 d = p - origin();
    return {glm::dot(d, across()), glm::dot(d, downhill())};
  }
  // Signed height of p above the glass (positive on the drop side).
  double height(const glm::dvec3& p) const { return glm::dot(p - origin(), normal()); }

  // Ray parameter where origin + t * dir meets the plane; nothing when the ray is parallel
  // to the plane (the pixel-to-glass denominator that the reference code divides by zero
  // with) or meets it behind the origin.
  std::optional<double> intersect(const glm::dvec3& ray_origin, const glm::dvec3& dir) const {
    const double denom = glm::dot(dir, normal());
    if (std::abs(denom) < 1e-12) return std::nullopt;
    const double t = glm::dot(origin() - ray_origin, normal()) / denom;
    if (!(t > 0) || !std::isfinite(t)) return std::nullopt;
    return t;
  }
};

}  // namespace raindrop
