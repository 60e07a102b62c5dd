#pragma once
// Tiling: images larger than a tile are processed as overlapping windows, so that the
// networks' memory (which grows with the pixel count: the paper's 3RN holds 256 channels at
// half resolution, 0.5 GB per tensor for a 1024x2048 image) stays bounded. Measured peak
// memory of raindrop-remove on a 1024x2048 image (ONNX Runtime 1.31, CPU, default arena):
//   paper networks:   11.7 GB whole, 5.8 GB with the default 1024 tile (3 windows),
//                     2.7 GB with --tile 768, 1.6 GB with --tile 512;
//   compact networks:  3.6 GB whole, 2.0 GB with the default tile.
// The default tile was also the fastest of these on the 2-core development machine (smaller
// working sets; 512 pays for its 18 windows' overlaps). --tile 0 turns tiling off.
//
// Per axis, a length L > tile becomes n windows of equal size (as small as the overlap
// allows, so the extra work is (n - 1) * overlap, not a whole tile), each starting at a
// multiple of `align`. align = lcm(2, pad_multiple): the RDN and 3RN have a stride-2
// convolution, and a window at an odd offset would sample the half-resolution grid
// differently from the whole image.
//
// Between two neighbouring windows, whose overlap is >= `overlap`, the cut point c is the
// middle of the overlap. Each window owns [c_left, c_right) (used for the detection
// probabilities, which are thresholded, so they are not blended), and its output is blended
// with a raised-cosine ramp of width overlap/2 centred on c. The ramp therefore starts
// overlap/4 pixels inside the window edge: with the default overlap of 128 that is 32
// pixels, more than the pipeline's receptive radius (the output depends on pixels up to
//   RFN radius + 3RN radius = (2 + 2 * rfn_blocks) + (5 + 2 * rrn_blocks)
// away: 27 for the paper's networks (8 3RN blocks, 2 RFN blocks), 19 for "compact"), so
// pixels used from a tile see no tile edge and the tiled output equals the whole-image one
// up to float rounding. Smaller overlaps still work, with the ramp hiding the seam.
#include <vector>

namespace raindrop::removal {

constexpr int kDefaultTile = 1024;    // largest window side; 0 = never tile
constexpr int kDefaultOverlap = 128;  // smallest overlap between neighbouring windows

// Throws raindrop::Error with a message naming --tile / --tile-overlap.
void check_tile_options(int tile, int overlap);

struct AxisLayout {
  std::vector<int> begin, end;  // window i is [begin[i], end[i])
  std::vector<int> cut;         // n - 1 cut points; window i owns [cut[i-1], cut[i])
  std::vector<int> ramp;        // n - 1 ramp half-widths (overlap_i / 4)

  int count() const { return static_cast<int>(begin.size()); }
  int owned_begin(int i) const { return i == 0 ? begin[0] : cut[i - 1]; }
  int owned_end(int i) const { return i + 1 == count() ? end[i] : cut[i]; }
  // Blend weight of window i at coordinate x; the weights of all windows sum to 1 (up to
  // one float rounding) at every x, and are 0 within overlap/4 of an inner window edge.
  float weight(int i, int x) const;
};

// length: the (padded) image side; tile: as check_tile_options; align >= 1.
AxisLayout layout_axis(int length, int tile, int overlap, int align);

}  // namespace raindrop::removal
