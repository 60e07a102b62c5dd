#pragma once
// One adherent drop: a spherical cap sitting on the outside of the glass.
//
// The cap is the part of a sphere of radius R above the glass plane; the contact angle tau
// between the glass and the cap's tangent at the rim fixes how much of the sphere shows:
//   footprint radius a = R sin(tau),   height h = R (1 - cos(tau)),   0 < tau <= 90 deg.
// The paper samples R ("r") and tau; the authors' released code samples a and tau. Both are
// exposed (see SceneConfig); internally the footprint radius is primary.
//
// Gravity (an optional effect) deforms the cap affinely in the glass frame: the footprint is
// stretched downhill by `elongation` and the height scaled by `flattening`. The cap is then
// a cap of an ellipsoid; intersection maps the ray into the frame where it is a sphere again,
// so the sphere is just the case elongation = flattening = 1.
//
// An irregular contact line (outline.h, optional) stretches the cap radially per azimuth in
// that scaled frame. The sphere's closed-form intersection then no longer applies; the ray is
// searched for sign changes of the surface's implicit function and each root refined
// (intersect_irregular). A circular outline takes the closed-form path, bit for bit as before.
#include <optional>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "raindrop/render/glass.h"
#include "raindrop/render/outline.h"

namespace raindrop {

enum class DropSurface { Base, Cap };

struct DropShape {
  glm::dvec2 center{0, 0};       // footprint centre (u across, v downhill) on the glass, cm
  double footprint_radius = 0.5; // a, cm (semi-axis across the glass)
  double contact_angle = 0.6;    // tau, radians, in (0, pi/2]
  double elongation = 1.0;       // downhill footprint semi-axis / a (gravity), >= 1
  double flattening = 1.0;       // height relative to the spherical cap (gravity), (0, 1]
  Outline outline;               // contact line: rim at a s(phi) across (circle by default)
  int trail_of = -1;             // index of the drop whose trail this cap is (trails.h), or -1

  double sphere_radius() const;
  double height() const;
  // Semi-axes of the ellipse that holds the footprint (across, downhill): the footprint
  // itself for a circular outline.
  glm::dvec2 footprint_semi_axes() const {
    const double a = footprint_radius * outline.s_max();
    return {a, a * elongation};
  }
};

struct SurfaceHit {
  double t = 0;                 // ray parameter
  DropSurface surface = DropSurface::Base;
  glm::dvec3 normal{0, 0, 0};   // unit normal pointing out of the water
};

class Drop {
 public:
  Drop(const DropShape& shape, const GlassPlane& glass);

  const DropShape& shape() const { return shape_; }

  // Nearest intersection of origin + t * dir (dir need not be unit) with the closed cap
  // (flat base on the glass plus curved surface), for t in (t_min, t_max). A ray that starts
  // on one of the drop's surfaces passes that surface as `start`, so the root at t = 0 is
  // removed exactly rather than by an epsilon. Computed in double precision.
  std::optional<SurfaceHit> intersect(const glm::dvec3& origin, const glm::dvec3& dir,
                                      double t_min, double t_max,
                                      std::optional<DropSurface> start = std::nullopt) const;

  // Outward unit normal of the curved surface at camera-space point p (on or near it).
  glm::dvec3 cap_normal(const glm::dvec3& p) const;
  glm::dvec3 base_normal() const { return -n_; }
  glm::dvec3 centre() const { return c_; }  // footprint centre, camera space

  // Camera-space point of the curved surface at polar angle theta in [0, tau] from the apex
  // and azimuth phi (theta = tau is the rim). Used to tessellate the cap.
  glm::dvec3 cap_point(double theta, double phi) const;
  // The same point on the cap of the circular outline of radius a s_max, which holds the drop
  // (the drop's height at (rho, phi) is cap(rho / s(phi)) <= cap(rho / s_max)) and is convex:
  // the image of a dense sample of these points bounds the drop's image.
  glm::dvec3 envelope_point(double theta, double phi) const;

  // The constants of the closed-form intersection, for tracing several rays side by side
  // with Drop::intersect's own arithmetic (cap_exit.h).
  struct Frame {
    glm::dvec3 c, u, v, n;  // footprint centre and glass frame (camera space)
    double radius, centre_height, inv_elongation, inv_flattening;
  };
  Frame frame() const { return {c_, u_, v_, n_, radius_, centre_height_, inv_elongation_, inv_flattening_}; }

  // Whether camera-space point p lies in the water (on or under the cap, on or above the glass).
  bool contains(const glm::dvec3& p) const;

  // Camera-space axis-aligned bounding box.
  void bounds(glm::dvec3* lo, glm::dvec3* hi) const;

 private:
  glm::dvec3 to_local(const glm::dvec3& p) const;   // scaled local frame: the cap is spherical
  glm::dvec3 dir_to_local(const glm::dvec3& d) const;
  // Implicit surface in the scaled frame: rho^2 / s(phi)^2 + (z - centre_height)^2 - R^2,
  // negative inside the (stretched) sphere.
  double implicit(const glm::dvec3& l) const;
  std::optional<SurfaceHit> intersect_irregular(const glm::dvec3& o, const glm::dvec3& d, double t_min,
                                                double t_max, std::optional<DropSurface> start) const;

  DropShape shape_;
  glm::dvec3 c_, u_, v_, n_;  // footprint centre and glass frame (camera space)
  double radius_;             // R of the sphere in the scaled frame
  double centre_height_;      // -R cos(tau): sphere centre below the glass, scaled frame
  double rim_radius2_;        // a^2
  double inv_elongation_, inv_flattening_;
};

}  // namespace raindrop
