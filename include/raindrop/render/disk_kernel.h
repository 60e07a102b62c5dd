#pragma once
// The disk kernel of a circle of confusion, row by row: each row a run of full-weight taps
// (summed with prefix sums, O(1) per row) and the partial taps of the rim one by one, so a
// disk d pixels wide costs O(d) per pixel instead of O(d^2). Shared by the paper's drop blur
// (blur.h) and the thin-lens layers (defocus.h), so that both use the same weights.
#include <utility>
#include <vector>

namespace raindrop {

// A kernel row: pixels [run_lo, run_hi] have weight 1, `taps` are the others.
struct KernelRow {
  int dy = 0;
  int run_lo = 1, run_hi = 0;  // empty when run_lo > run_hi
  std::vector<std::pair<int, float>> taps;
};

// The rows of the disk of `diameter` pixels centred on a pixel, unnormalised. `antialiased`:
// each tap weighted by the area of its pixel inside the disk; else 1 where the pixel's centre
// is inside. `split_runs`: full-weight taps go into each row's run (else all are taps). A disk
// inside the centre pixel (diameter <= 1) is the identity.
std::vector<KernelRow> disk_rows(double diameter, bool antialiased, bool split_runs);

}  // namespace raindrop
