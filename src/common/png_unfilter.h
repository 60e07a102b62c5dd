#pragma once
// Undoing PNG's row filters (None, Sub, Up, Average, Paeth) of inflated image data, for the
// decoder of png_file.h. Runs of Paeth rows of 8-bit RGB or RGBA (most rows of most photographs'
// PNGs) are undone four or eight at a time as a wavefront where the processor has AVX2 or
// AVX-512 (a row's pixels depend on each other one after another; rows' chains run side by side);
// everything else row by row. Integer arithmetic: the same pixels whichever path. Internal to
// raindrop_common.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include <opencv2/core.hpp>

namespace raindrop::png {

// PNG's Paeth predictor of a byte from its left (a), upper (b) and upper-left (c) neighbours.
inline int paeth_predictor(int a, int b, int c) {
  const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
  const int b_or_c = pb <= pc ? b : c;  // two selects the compiler makes branch-free
  return pa <= pb && pa <= pc ? a : b_or_c;
}

// Copies `bytes` bytes of 16-bit samples, swapping each sample's two bytes (PNG's big-endian
// order to or from the order of a little-endian machine's cv::Mat).
inline void copy_swapping_16_bit(const std::uint8_t* from, std::uint8_t* to, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; i += 2) to[i] = from[i + 1], to[i + 1] = from[i];
}

// The rows of `raw` (`height` rows, each a filter-type byte and `stride` bytes of `width` pixels
// of `bpp` bytes) undone into `image` (height x width, continuous, with the file's depth and
// channels). 8-bit rows go from `raw` straight into `image`'s rows; 16-bit ones are undone in
// place and then copied into `image`, their bytes swapped where `swap` (a little-endian machine).
// False at a filter type past 4 (the image is then incomplete).
bool unfilter(std::uint8_t* raw, std::size_t stride, std::size_t bpp, std::size_t width, std::size_t height,
              bool swap, cv::Mat& image);

// The widest registers this processor gives the PNG row loops (the writer's Paeth filter and the
// Paeth bands here): 0 SSE2 only, 1 AVX2, 2 AVX-512 with byte and word operations (AVX512BW).
int simd_level();

// Tests: the widest bands unfilter may use: 0 row by row, 1 four rows (AVX2), 2 eight rows
// (AVX-512), each where the processor has it. The same pixels at every level. Returns the widest
// this processor has.
int limit_paeth_bands(int level);

}  // namespace raindrop::png
