#pragma once
// Rays inside drops leaving through their caps, several side by side in SIMD arithmetic.
//
// A camera ray that has come into a drop through its base leaves through the cap, the only
// surface it can meet when drops are disjoint. Drop::intersect answers that one ray at a
// time: a chain of square roots and divisions (the sphere's roots, then the normal), each
// waiting on the one before. Here the rays of a packet take the same steps two at a time in
// SSE2 registers (the x86-64 baseline, so the binary stays the same for every machine). Each
// lane does Drop::intersect's arithmetic in Drop::intersect's order, and IEEE addition,
// multiplication, division and square root round the same in a register as alone, so every
// answer is Drop::intersect's to the bit (tests/render/test_cap_exit.cpp).
#include <glm/vec3.hpp>

#include "raindrop/render/drop.h"

namespace raindrop {

struct CapExit {
  bool hit = false;
  double t = 0;                 // ray parameter of the exit point
  glm::dvec3 normal{0, 0, 0};   // the cap's unit normal there, pointing out of the water
};

// For i < n (1 <= n <= 8): what drops[i]->intersect(origins[i], dirs[i], 0.0, t_max[i],
// DropSurface::Base) gives (a ray starting on the drop's base, inside its water), for drops of
// circular outline. The hit is always on the cap.
void exit_through_caps(const Drop* const* drops, const glm::dvec3* origins, const glm::dvec3* dirs,
                       const double* t_max, int n, CapExit* out);

}  // namespace raindrop
