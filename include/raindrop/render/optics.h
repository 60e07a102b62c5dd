#pragma once
// Geometric optics at a smooth interface between two dielectrics. Directions are unit
// vectors; `normal` is the unit surface normal on the side the ray comes from
// (dot(dir, normal) <= 0). All functions are total: they return a finite result or report
// total internal reflection, for any unit input including grazing and tangent rays.
#include <algorithm>
#include <cmath>
#include <optional>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace raindrop {

// Refractive index of water at 20 C for the sodium D line, as in the paper.
inline constexpr double kWaterIndex = 1.333;

// Water at 20 C by the Cauchy fit n = A + B / lambda^2 (lambda in micrometres) through the
// C and F lines (1.3312 at 656 nm, 1.3371 at 486 nm); it gives 1.3329 at the D line
// (589 nm, tabulated 1.3330). Used by the
// dispersion effect; red, green and blue are taken at 620, 540 and 460 nm.
inline double water_index(double wavelength_um) {
  constexpr double A = 1.32403, B = 0.003089;
  return A + B / (wavelength_um * wavelength_um);
}

// Critical angle for light inside a medium of index n_inside going out into n_outside.
inline double critical_angle(double n_inside, double n_outside = 1.0) {
  return std::asin(std::clamp(n_outside / n_inside, -1.0, 1.0));
}

inline glm::dvec3 reflect(const glm::dvec3& dir, const glm::dvec3& normal) {
  return dir - 2.0 * glm::dot(dir, normal) * normal;
}

// Snell's law in vector form. eta = n_from / n_to. Returns nothing on total internal
// reflection. The cosine is clamped so that a ray exactly tangent to the surface (cos = 0)
// or numerically past it gives a well-defined grazing result instead of NaN.
inline std::optional<glm::dvec3> refract(const glm::dvec3& dir, const glm::dvec3& normal,
                                         double eta) {
  const double cos_i = std::clamp(-glm::dot(dir, normal), 0.0, 1.0);
  const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
  if (sin2_t > 1.0) return std::nullopt;  // beyond the critical angle
  const double cos_t = std::sqrt(1.0 - sin2_t);
  return glm::normalize(eta * dir + (eta * cos_i - cos_t) * normal);
}

// Unpolarised Fresnel reflectance for incidence cosine cos_i (>= 0), eta = n_from / n_to.
// 1 on total internal reflection.
inline double fresnel_reflectance(double cos_i, double eta) {
  cos_i = std::clamp(cos_i, 0.0, 1.0);
  const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
  if (sin2_t >= 1.0) return 1.0;
  const double cos_t = std::sqrt(1.0 - sin2_t);
  const double rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const double rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const double r = 0.5 * (rs * rs + rp * rp);
  return std::clamp(std::isfinite(r) ? r : 1.0, 0.0, 1.0);
}

}  // namespace raindrop
