#pragma once
// Which drops a thin lens's rays can meet: the aperture reference's culling.
//
// The aperture reference (trace_aperture) averages, for each pixel, rays from points of the
// lens disk (radius a, z = 0) through the pixel's point f on the plane of focus (z = F). A
// ray from lens point o crosses depth z at (z/F) f + (1 - z/F) o, so all of a pixel's rays
// cross depth z inside the disk of centre (z/F) f and radius |1 - z/F| a: a cone. A drop lies
// inside its bounding sphere, which lies between the depths z0 and z1; over those depths the
// cone stays within a capsule: the segment from z0 f / F to z1 f / F, widened by the larger of
// its two end radii (|1 - z/F| is convex in z). A pixel whose capsule passes farther than the
// sphere's radius from the sphere's centre has no ray that meets the drop, and a ray whose
// line passes farther than the radius from the centre does not meet it either.
//
// Both tests are conservative (the sphere and the capsule are padded far beyond rounding), so
// a culled ray is one whose Embree query would have found no drop: what the reference renders
// is unchanged to the bit (tests/render/test_aperture_reach.cpp), only fewer rays are traced.
#include <vector>

#include <glm/vec3.hpp>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/spans.h"

namespace raindrop {

class ApertureReach {
 public:
  // `aperture_radius_cm`: the lens disk's radius a; `focus_cm`: F.
  ApertureReach(const std::vector<Drop>& drops, double aperture_radius_cm, double focus_cm);

  // Whether some ray from the lens disk through `focus` (a point of the plane z = F) can
  // meet drop `drop`.
  bool cone_meets(int drop, const glm::dvec3& focus) const;
  // Whether the line through `origin` along `dir` (any length) can meet drop `drop`.
  bool ray_meets(int drop, const glm::dvec3& origin, const glm::dvec3& dir) const;

  // Per image row, a box of pixels per drop whose cones can meet it, sorted by first pixel: the
  // pinhole image of the drop's bounding box (the hull of its eight corners' images, unclipped,
  // so that a drop just outside the frame still reaches in) widened by half the largest circle
  // of confusion over its depths, plus a pixel. A ray from lens point o towards pixel p's point
  // on the plane of focus crosses depth z at (1 - z/F) o off the pinhole ray of p, which the
  // pinhole projects within half the circle at z of p; the circle is largest at one end of the
  // drop's depth range. Each drop by its own reach: small drops far from the lens' nearest glass
  // reach few pixels.
  static std::vector<std::vector<DropSpan>> candidate_boxes(const Camera& camera, const SceneSample& scene,
                                                            const std::vector<Drop>& drops);
  // The drops of one row's candidate boxes that pixel x's cone meets (`focus`: its point on the
  // plane of focus), into `near`.
  void near_drops(const std::vector<DropSpan>& row_boxes, int x, const glm::dvec3& focus, std::vector<int>* near) const;

 private:
  struct Sphere {
    glm::dvec3 centre;
    double radius;
    double z0, z1;      // the depths it spans
    double cone_reach;  // the capsule's radius over [z0, z1], plus the sphere's radius
  };
  std::vector<Sphere> spheres_;
  double inv_focus_;
};

}  // namespace raindrop
