#pragma once
// The pinhole camera's rays traced in SIMD lanes, one drop at a time.
//
// In the paper's scenes nearly every traced pixel takes one path: its ray crosses the glass
// inside one drop's footprint, refracts into the water through the flat base, leaves through
// the cap (or is totally internally reflected there: the dark band) and goes on to the street
// with no other drop in reach. Traced one ray at a time, that path is a chain of square roots
// and divisions behind an Embree query whose callbacks cost as much again. Here a row's rays
// are taken a drop at a time, over the pixels whose rays can reach that drop (the tracer's
// spans, kept per drop), as many lanes at a time as a register holds doubles, with the
// drop's constants the same in every lane:
//
//   1. first hits: Drop::intersect of each ray with the drop (base, then the cap's roots);
//      over the drops whose spans cover a pixel, the nearest hit, ties to the lower index:
//      what the Embree query answers (drop_accel.cpp);
//   2. the common path of the rays whose first hit is this drop's base: refraction in,
//      the exit through the cap (cap_exit.h), refraction out, and the exit ray's slab range.
//
// Every step is the scalar code's arithmetic in its order (the build has -ffp-contract=off;
// IEEE addition, multiplication, division and square root round the same in a lane as
// alone), so each ray gets trace_path's answer to the bit. Two assumptions: a drop's span
// covers every pixel whose ray meets it (the tracer's conservative hull of the drop's image,
// padded far beyond the sampling error), and no two drops' surfaces meet a ray within a
// rounding error of each other (drops that touch to 1e-16: there Embree's answer depends on
// the order it visits them in; the lanes give the nearer, ties to the lower index). A ray that leaves the common path
// anywhere (a cap met from outside, a refraction that fails, another drop in reach) is marked
// for the one-at-a-time tracer, which handles everything. The lanes run in AVX-512, AVX2 or
// SSE2 registers, whichever the processor has (chosen at run time: one binary runs anywhere,
// and every width gives the same bits; tests/render/test_pinhole_lanes.cpp).
//
// Only where every drop is an exact cap of circular outline and drops are disjoint
// (`applies`); Fresnel's transmittances included, not dispersion (whose kernel keeps its path).
// Built with GCC for x86-64 only (`available`; elsewhere the tracer keeps its own path).
#include <cstdint>
#include <vector>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/render/glass.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/tracer.h"

namespace raindrop {

namespace lanes_detail {
// The frame's constants, as the scalar code computes them (pinhole_lanes.cpp).
struct SceneConstants {
  double cx, cy, fx, fy;   // camera
  double gp[3], gn[3];     // glass: a point and the unit normal (GlassFrame)
  double top;              // DropAccel::slab_top
  double h0;               // slab_range's height of the camera's centre above the glass
  double eta_in, eta_out;  // 1 / n_water, n_water
  double background_z;     // the background plane, z = background_z
  bool tir_black;
  bool fresnel;            // transmittances traced (Fresnel)
};
// One drop's constants (Drop::intersect's, for the camera's centre as origin).
struct DropConstants {
  double c[3], u[3], v[3], n[3];  // footprint centre and glass frame
  double radius, centre_height, inv_e, inv_f, rim2;
  double o[3];   // to_local(camera centre)
  double oc_z;   // o.z - centre_height
  double c_sq;   // dot(oc, oc) - R^2
  double hn[3];  // the base's normal, -n
};
// Rays o + t d of any origins (trace_rays), directions normalised; each array padded to a
// multiple of 8 (the lanes read whole registers).
struct RayArrays {
  const double *ox, *oy, *oz, *dx, *dy, *dz;
};
}  // namespace lanes_detail

class PinholeLanes {
 public:
  enum class Outcome : std::uint8_t {
    Miss,   // meets no drop
    Path,   // traced here: the Row's arrays at x (Row::path)
    Alone,  // left the common path: trace it one ray at a time
  };
  // A row's results, indexed by x: trace_row grows the arrays to the furthest span end it has
  // been given and sets them over its spans only.
  struct Row {
    std::vector<Outcome> outcome;
    // Where outcome is Path: the drop met first, and how the ray ended (a State).
    std::vector<int> drop;
    std::vector<std::uint8_t> state;
    // The exit ray o + t d and the background point it sees (unset for a dark path).
    std::vector<double> ox, oy, oz, dx, dy, dz, seen_x, seen_y;
    std::vector<double> transmittance;  // Fresnel's product (1 without it)
    // Scratch: the nearest first hit so far, whether on a base, the exit ray's slab range.
    std::vector<double> t, range;
    std::vector<std::uint8_t> base;

    bool dark(int x) const { return state[x] == kTrapped || state[x] == kDarkBand; }
    bool escaped_in(int x) const { return (state[x] & kEscaped) != 0; }
    // trace_path's DropPath for a Path pixel.
    DropPath path(int x) const;
  };
  // How a traced ray ended, one of five values: left the common path (kAlone), no way out
  // of the water (kTrapped: dark), the dark band, out of the drop (kOutSlab: within the slab,
  // where may_meet_after_exit decides); to kOut and kOutSlab the bit kEscaped is added when
  // the ray heads back through the glass. Compare values, not bits: (state & ~kEscaped).
  enum State : std::uint8_t { kAlone = 1, kTrapped = 2, kDarkBand = 3, kOut = 4, kOutSlab = 5, kEscaped = 8 };

  // Whether this build has the lanes (GCC on x86-64).
  static bool available();
  // Whether the lanes can trace this accelerator's drops: available, exact caps, all of
  // circular outline, disjoint.
  static bool applies(const DropAccel& accel);

  PinholeLanes(const Camera& camera, const DropAccel& accel, const GlassPlane& glass, double background_z,
               double n_water, TirMode tir, bool fresnel);

  // The camera rays through the pixels of row y that `spans` cover (one row's DropSpans, at
  // most one per drop; a pixel may lie in several drops' spans): row->outcome[x] for each,
  // and where it is Path the row's other arrays at x. Returns how many were traced here
  // (Outcome::Path).
  int trace_row(int y, const std::vector<DropSpan>& spans, Row* row) const;

  // Rays 0..n-1 of `rays` (an aperture pixel's: any origins, directions normalised as
  // trace_packet normalises them) against `drops`, which must hold every drop any of them can
  // meet (ApertureReach): row->outcome[i] for each as trace_row gives it, and where it is Path
  // the row's other arrays at i. Returns how many were traced here.
  int trace_rays(const lanes_detail::RayArrays& rays, int n, const std::vector<int>& drops, Row* row) const;

  // The register width used: 2 AVX-512, 1 AVX2, 0 SSE2 (the widest the processor has,
  // unless force_level lowered it: for tests).
  static int level();
  static void force_level(int level);  // -1: the widest again

 private:
  bool alone(const Row& r, int i) const;

  const DropAccel& accel_;
  lanes_detail::SceneConstants scene_;
  std::vector<lanes_detail::DropConstants> drops_;
};

}  // namespace raindrop
