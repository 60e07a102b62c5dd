#pragma once
// Embree 3 acceleration structure over the drops of one frame, answering "which drop
// surface does this ray meet first". Two representations, the accuracy/time knob:
//  - exact:  one Embree user-geometry primitive per drop; the intersection callback solves
//            the cap analytically in double precision (raindrop::Drop::intersect);
//  - mesh:   each cap tessellated into triangles (`segments` around, segments/4 rings from
//            the apex to the rim) plus a triangle fan for the base; normals either flat
//            (the triangle's) or smooth (vertex normals of the true surface, interpolated).
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "raindrop/drop.h"

namespace raindrop {

struct GeometryOptions {
  enum class Kind { Exact, Mesh } kind = Kind::Exact;
  int segments = 32;          // mesh only: triangles around the rim
  bool smooth_normals = true; // mesh only

  std::string describe() const;  // "exact", "mesh-32-smooth", ...
  static GeometryOptions parse(const std::string& text);  // inverse of describe()
};

struct DropHit {
  double t = 0;
  int drop = -1;
  DropSurface surface = DropSurface::Base;
  glm::dvec3 normal{0, 0, 0};  // unit, pointing out of the water
};

class DropAccel {
 public:
  DropAccel(const std::vector<Drop>& drops, const GeometryOptions& options);
  ~DropAccel();
  DropAccel(const DropAccel&) = delete;
  DropAccel& operator=(const DropAccel&) = delete;

  // First drop surface met by origin + t * dir with t in (t_min, t_max). `from` is the hit
  // the ray starts at, if any, so that the ray does not find its own starting point again.
  std::optional<DropHit> intersect(const glm::dvec3& origin, const glm::dvec3& dir,
                                   const DropHit* from = nullptr, double t_min = 0.0,
                                   double t_max = std::numeric_limits<double>::infinity()) const;

  // The first surface met by a ray that is inside the water of drop `from.drop`. When drops
  // are disjoint (`set_disjoint`; footprints apart, so caps apart) and caps are exact, the
  // ray can only leave through that drop's own surface: answered analytically, no Embree
  // query. Otherwise the same as intersect().
  std::optional<DropHit> intersect_inside(const glm::dvec3& origin, const glm::dvec3& dir, const DropHit& from,
                                          double t_max = std::numeric_limits<double>::infinity()) const;
  void set_disjoint(bool disjoint) { disjoint_ = disjoint; }

  // Every drop lies between the glass plane and this height above it (cm).
  double max_height() const { return max_height_; }

  const std::vector<Drop>& drops() const { return drops_; }
  const GeometryOptions& options() const { return options_; }

 private:
  struct Impl;
  std::vector<Drop> drops_;
  GeometryOptions options_;
  double max_height_ = 0;
  bool disjoint_ = false;
  std::unique_ptr<Impl> impl_;
};

}  // namespace raindrop
