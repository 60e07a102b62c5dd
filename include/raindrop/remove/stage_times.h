#pragma once
// Wall-clock time per pipeline stage, summed over tiles (milliseconds). In tiled runs the
// input conversion and edge map are counted twice: pass 1 (detection) and pass 2
// (reconstruction) rebuild each tile's inputs instead of keeping them all in memory.
#include <string>

namespace raindrop::removal {

struct StageTimes {
  double convert = 0;  // input -> float RGB, padding, NCHW layout
  double edge = 0;     // edge map
  double rdn = 0;      // detection network
  double mask = 0;     // threshold + dilation
  double rrn = 0;      // 3RN, with the clamp
  double blend = 0;    // B = M * Ihat + (1 - M) * R
  double rfn = 0;      // refine network, with the clamp
  double output = 0;   // tile blending, cropping, quantisation, grey/alpha
  // The detector router (detector_router.h): its features and choice, loading the alternative
  // detector on the first routed image, and the coarse pass waiting for the choice (its own
  // detector ran meanwhile). The alternative's run counts as RDN.
  double router = 0;

  double total() const { return convert + edge + rdn + mask + rrn + blend + rfn + output + router; }
  StageTimes& operator+=(const StageTimes& o);
  StageTimes& operator/=(double n);
  // "edge 1.2, rdn 30.5, ... ms; stages summed ... ms" for --time. Stages that ran side by side
  // (RDN beside 3RN, the coarse pass beside the working pass) each count their own time, so the
  // sum exceeds the image's wall time on two or more threads.
  std::string describe() const;
};

}  // namespace raindrop::removal
