#pragma once
// What the renderer's process asks of the C library's allocator.
//
// A frame allocates and frees the same tens of megabytes each time: the rainy image, the
// coverage, each drop's layer. By default glibc hands every block above its threshold (128 KiB,
// adapting up to 32 MiB) back to the kernel when it is freed, so the next frame pays page faults
// and freshly zeroed pages again (2-10% of a frame, docs/RESULTS.md 1.2). Raising the threshold
// to glibc's largest and keeping up to 1 GiB freed at the top of the heap lets a frame's freed
// memory serve the next. The process's peak memory is what it was (measured: +4-10% of the
// renderer's); blocks above 32 MiB still come from the kernel.
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace raindrop {

// Call once at the start of main, before any thread starts. No effect without glibc.
inline void keep_freed_frame_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
#endif
}

}  // namespace raindrop
