#pragma once
// A pixel's four floats (RGB and a pad, or premultiplied RGB and coverage) in SIMD registers,
// as GCC/Clang vector extensions: one pixel per SSE2 register (f4), two per AVX register (f8),
// four per AVX-512 register (f16). Neighbouring pixels' f4 are neighbours in memory, so one
// wide load reads several pixels, and a lane's additions, subtractions and multiplications
// round as the one-pixel ones do (the build has -ffp-contract=off: no fused multiply-add).
// Shared by the disk blur (blur.cpp) and the thin lens's spread (defocus_rows.cpp), which
// choose the width when the program runs (blur_simd_level_used).
namespace raindrop::pixel_vectors {

typedef float f4 __attribute__((vector_size(16)));
typedef float f8 __attribute__((vector_size(32)));
typedef float f16 __attribute__((vector_size(64)));

// Neighbouring pixels' f4 from p on into v, unaligned (memcpy compiles to one load; a wide
// vector returned by value would trip GCC's ABI warning outside the target functions).
template <typename V>
static inline __attribute__((always_inline)) void load(V& v, const f4* p) {
  __builtin_memcpy(&v, p, sizeof v);
}

}  // namespace raindrop::pixel_vectors
