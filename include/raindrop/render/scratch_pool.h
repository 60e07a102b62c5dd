#pragma once
// Large scratch buffers of one frame's trace and blur (the label and colour images, the blur's
// source and prefix sums: about 100 MB at 2048x1024), kept for the next frame instead of
// being handed back to the system. Buffers that size come from fresh pages of memory each
// time they are allocated, and the kernel faults in and zeroes every page the frame touches:
// about a tenth of the render core's time (docs/RESULTS.md, section 1.2). A buffer holds its
// last user's bytes: like any uninitialised memory, every element must be written before it
// is read. The pool keeps at most kScratchBuffersKept free buffers; memory stays at the
// peak that the frames in flight needed at once.
#include <cstddef>
#include <memory>

#include <opencv2/core/mat.hpp>

namespace raindrop {

inline constexpr int kScratchBuffersKept = 16;

struct ScratchRelease {
  void operator()(std::byte* data) const;  // back to the pool
};
using ScratchBytes = std::unique_ptr<std::byte[], ScratchRelease>;

// At least `bytes` bytes, 64-byte aligned, from the pool (the smallest free buffer that is large
// enough) or newly allocated. Thread-safe.
ScratchBytes scratch_bytes(std::size_t bytes);

// A matrix whose data comes from the pool and returns to it when its last header is gone
// (a cv::MatAllocator): uninitialised, like cv::Mat(rows, cols, type).
cv::Mat scratch_mat(int rows, int cols, int type);

// How many buffers the pool holds free now (for tests).
int scratch_buffers_free();

}  // namespace raindrop
