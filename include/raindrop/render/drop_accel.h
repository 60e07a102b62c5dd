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

#include "raindrop/render/drop.h"

namespace raindrop {

// The finest mesh: a cap of `segments` takes about segments^2 / 2 triangles, so memory grows
// with its square ("mesh-4096-flat" passed validation and allocated until the machine killed
// it). 256 is the unit tests' reference mesh; beyond 128 a mesh is slower than the exact caps
// and no more accurate (docs/RESULTS.md), so finer meshes have no use.
inline constexpr int kMaxMeshSegments = 256;
// The most memory one sample's mesh may take (scene validation refuses more): a scene file must
// not be able to exhaust the machine with segments x drops.
inline constexpr double kMaxMeshBytes = 2.0 * (1 << 30);

struct GeometryOptions {
  enum class Kind { Exact, Mesh } kind = Kind::Exact;
  int segments = 32;          // mesh only: triangles around the rim
  bool smooth_normals = true; // mesh only

  // Memory the mesh takes per drop: measured about 70 bytes per segments^2 (vertices, normals,
  // triangles, Embree's BVH; 4.5 MB a drop at 256); exact caps: a few hundred bytes, 0 here.
  double mesh_bytes_per_drop() const { return kind == Kind::Mesh ? 72.0 * segments * segments : 0.0; }

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

  // intersect() with no starting surface for n rays (n <= 8: camera rays through neighbouring
  // pixels, or one pixel's rays from points of the aperture), as one Embree packet query for
  // exact caps: the rays take nearly the same path through the tree, walked once for all of
  // them. hits[i] is what intersect(origins[i], dirs[i], nullptr, t_min[i], t_max[i]) gives.
  void intersect_packet(const glm::dvec3* origins, const glm::dvec3* dirs, const double* t_min, const double* t_max,
                        int n, std::optional<DropHit>* hits) const;

  // The first surface met by a ray that is inside the water of drop `from.drop`. When drops
  // are disjoint (`set_disjoint`; footprints apart, so caps apart) and caps are exact, the
  // ray can only leave through that drop's own surface: answered analytically, no Embree
  // query. Otherwise the same as intersect().
  std::optional<DropHit> intersect_inside(const glm::dvec3& origin, const glm::dvec3& dir, const DropHit& from,
                                          double t_max = std::numeric_limits<double>::infinity()) const;
  void set_disjoint(bool disjoint) { disjoint_ = disjoint; }
  bool disjoint() const { return disjoint_; }

  // Whether point p, near the surface of drop `drop`, lies in the water of another drop
  // (one whose bounding box meets this drop's): overlapping drops are one body of water, and
  // the tracer asks this to tell their inner surfaces from the water's boundary.
  bool in_other_water(const glm::dvec3& p, int drop) const;

  // Whether a ray that has just left drop `drop` at `origin`, going along `dir` for t in
  // [0, t_max], can meet another drop. False only where that is sure, and then the tracer
  // skips the query: the ray's segment misses the bounding boxes of the drop's nearest
  // neighbours and is too short to reach the others. Only for exact caps of circular
  // outline (convex: a ray that leaves one cannot meet it again); elsewhere always true.
  bool may_meet_after_exit(int drop, const glm::dvec3& origin, const glm::dvec3& dir, double t_max) const;
  // Off: every exit is queried (for tests that hold the skip to the full query).
  void set_exit_skip(bool on) { exit_skip_ = on; }

  // Every drop lies between the glass plane and this height above it (cm).
  double max_height() const { return max_height_; }
  // The top of the layer the tracer limits each query to: max_height, padded far beyond the
  // rounding of the heights it is compared with.
  double slab_top() const { return max_height_ * (1 + 1e-9) + 1e-9; }

  const std::vector<Drop>& drops() const { return drops_; }
  const GeometryOptions& options() const { return options_; }

 private:
  struct Impl;
  std::vector<Drop> drops_;
  GeometryOptions options_;
  double max_height_ = 0;
  // Per drop: its nearest neighbours by bounding-box distance, and the distance beyond which
  // others may lie (may_meet_after_exit).
  static constexpr int kExitNeighbours = 8;
  struct ExitNeighbours {
    int count = 0;
    int drop[kExitNeighbours];
    double distance[kExitNeighbours];
    double beyond = 0;  // no other drop's box is nearer than this, outside the list
  };
  std::vector<ExitNeighbours> exit_neighbours_;
  std::vector<glm::dvec3> box_lo_, box_hi_;  // padded bounding boxes
  std::vector<std::vector<int>> box_overlaps_;  // per drop, the others whose boxes meet its box
  bool exit_skip_ = true;
  bool disjoint_ = false;
  std::unique_ptr<Impl> impl_;
};

}  // namespace raindrop
