#include "png_unfilter.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace raindrop::png {
namespace {

// Undoes the Paeth filter of one row, `src` (filtered) into `dst` (which may be `src`), a pixel
// at a time: each of the BPP byte chains depends on its own left neighbour only, so the BPP
// chains run side by side (in a scratch timing of a 2048x1024 RGB frame: 13 ms, against 21 for
// the plain byte loop).
template <std::size_t BPP>
void unpaeth(const std::uint8_t* src, std::uint8_t* dst, const std::uint8_t* above, std::size_t stride) {
  int left[BPP] = {0}, upper_left[BPP] = {0};  // zeros before the first pixel: Paeth is then Up
  for (std::size_t i = 0; i < stride; i += BPP) {
    for (std::size_t k = 0; k < BPP; ++k) {
      const int up = above[i + k];
      left[k] = static_cast<std::uint8_t>(src[i + k] + paeth_predictor(left[k], up, upper_left[k]));
      dst[i + k] = static_cast<std::uint8_t>(left[k]);
      upper_left[k] = up;
    }
  }
}

// Pixels [x0, x1) of a Paeth row, src into dst, the pixels before x0 (and above them) already
// undone: unpaeth's arithmetic from a given start, for the corners that unpaeth_band leaves.
template <std::size_t BPP>
void unpaeth_range(const std::uint8_t* src, std::uint8_t* dst, const std::uint8_t* above, std::size_t x0,
                   std::size_t x1) {
  for (std::size_t x = x0; x < x1; ++x) {
    for (std::size_t k = 0; k < BPP; ++k) {
      const std::size_t i = x * BPP + k;
      const int left = x > 0 ? dst[i - BPP] : 0, upper_left = x > 0 ? above[i - BPP] : 0;
      dst[i] = static_cast<std::uint8_t>(src[i] + paeth_predictor(left, above[i], upper_left));
    }
  }
}

#if defined(__x86_64__) && defined(__GNUC__)
// A pixel's BPP bytes as the low bytes of an int (no byte past them read).
template <std::size_t BPP>
inline int band_pixel(const std::uint8_t* p) {
  std::uint32_t v = 0;
  std::memcpy(&v, p, BPP);
  return static_cast<int>(v);
}

// Four consecutive Paeth rows of BPP (3 or 4) bytes per pixel, `width` >= 4 pixels, undone at
// once as a wavefront, from `src` (the filtered rows, `src_pitch` bytes from one to the next)
// into `dst` (`dst_pitch`): at step t, row k undoes its pixel t - k, whose left neighbour row k
// made one step before and whose upper neighbours row k - 1 made one and two steps before. The
// four rows' chains of dependent steps then run side by side in one AVX2 register (four slots of
// four 16-bit lanes, a pixel's bytes), where one row's chain left the processor waiting on each
// step's latency. Every lane does unpaeth's integer arithmetic: the same bytes. The corners where
// a row has no pixel at a step (its first 3 - k pixels and last k) are unpaeth_range's; slot 0
// reads its upper neighbours from `above`, the row over the band, four bytes at a time (for BPP
// 3 the fourth is ignored: lanes do not mix), so `above` needs a byte after its last pixel. Each
// slot stores exactly its pixel's bytes.
template <std::size_t BPP>
__attribute__((target("avx2"), always_inline)) inline void unpaeth_band4_avx2(const std::uint8_t* src,
                                                                             std::size_t src_pitch, std::uint8_t* dst,
                                                                             std::size_t dst_pitch,
                                                                             const std::uint8_t* above,
                                                                             std::size_t width) {
  static_assert(BPP == 3 || BPP == 4, "a pixel per slot of four lanes");
  const std::uint8_t* in[4] = {src, src + src_pitch, src + 2 * src_pitch, src + 3 * src_pitch};
  std::uint8_t* out[4] = {dst, dst + dst_pitch, dst + 2 * dst_pitch, dst + 3 * dst_pitch};
  for (int k = 0; k < 3; ++k)
    unpaeth_range<BPP>(in[k], out[k], k == 0 ? above : out[k - 1], 0, static_cast<std::size_t>(3 - k));
  // Slot k's pixel 2 - k (prev) and 1 - k (prev2), those before the first step t = 3.
  __m256i prev = _mm256_cvtepu8_epi16(
      _mm_setr_epi32(band_pixel<BPP>(out[0] + 2 * BPP), band_pixel<BPP>(out[1] + BPP), band_pixel<BPP>(out[2]), 0));
  __m256i prev2 = _mm256_cvtepu8_epi16(_mm_setr_epi32(band_pixel<BPP>(out[0] + BPP), band_pixel<BPP>(out[1]), 0, 0));
  // Row k's filtered pixel t - k lies at src + t BPP + k (src_pitch - BPP): one gather for the four.
  const __m128i offsets = _mm_setr_epi32(0, static_cast<int>(src_pitch - BPP), static_cast<int>(2 * (src_pitch - BPP)),
                                         static_cast<int>(3 * (src_pitch - BPP)));
  const __m256i low_byte = _mm256_set1_epi16(0xff);
  for (std::size_t t = 3; t < width; ++t) {
    // Four bytes a slot: for BPP 3 the fourth is the next pixel's first (or the next row's filter
    // type), ignored.
    const __m256i x =
        _mm256_cvtepu8_epi16(_mm_i32gather_epi32(reinterpret_cast<const int*>(src + t * BPP), offsets, 1));
    // Upper neighbours: slot k - 1's last two outputs moved up a slot; slot 0's from `above`,
    // read four bytes at once: a pixel assembled from narrower loads stalled the chain on a store
    // that could not be forwarded.
    std::int32_t up, up_left;
    std::memcpy(&up, above + t * BPP, 4);
    std::memcpy(&up_left, above + (t - 1) * BPP, 4);
    const __m256i b = _mm256_blend_epi32(_mm256_permute4x64_epi64(prev, _MM_SHUFFLE(2, 1, 0, 0)),
                                         _mm256_cvtepu8_epi16(_mm_cvtsi32_si128(up)), 0x03);
    const __m256i c = _mm256_blend_epi32(_mm256_permute4x64_epi64(prev2, _MM_SHUFFLE(2, 1, 0, 0)),
                                         _mm256_cvtepu8_epi16(_mm_cvtsi32_si128(up_left)), 0x03);
    const __m256i a = prev;
    const __m256i b_c = _mm256_sub_epi16(b, c), a_c = _mm256_sub_epi16(a, c);
    const __m256i pa = _mm256_abs_epi16(b_c), pb = _mm256_abs_epi16(a_c), pc = _mm256_abs_epi16(_mm256_add_epi16(b_c, a_c));
    // a where pa <= pb and pa <= pc; else b where pb <= pc; else c.
    const __m256i not_a = _mm256_or_si256(_mm256_cmpgt_epi16(pa, pb), _mm256_cmpgt_epi16(pa, pc));
    const __m256i b_or_c = _mm256_blendv_epi8(b, c, _mm256_cmpgt_epi16(pb, pc));
    const __m256i predictor = _mm256_blendv_epi8(a, b_or_c, not_a);
    const __m256i result = _mm256_and_si256(_mm256_add_epi16(x, predictor), low_byte);
    const __m128i bytes = _mm_packus_epi16(_mm256_castsi256_si128(result), _mm256_extracti128_si256(result, 1));
    const std::uint32_t v0 = static_cast<std::uint32_t>(_mm_cvtsi128_si32(bytes));
    const std::uint32_t v1 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 1));
    const std::uint32_t v2 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 2));
    const std::uint32_t v3 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 3));
    std::memcpy(out[0] + t * BPP, &v0, BPP);
    std::memcpy(out[1] + (t - 1) * BPP, &v1, BPP);
    std::memcpy(out[2] + (t - 2) * BPP, &v2, BPP);
    std::memcpy(out[3] + (t - 3) * BPP, &v3, BPP);
    prev2 = prev;
    prev = result;
  }
  for (int k = 1; k < 4; ++k)
    unpaeth_range<BPP>(in[k], out[k], out[k - 1], width - static_cast<std::size_t>(k), width);
}

__attribute__((target("avx2"))) void unpaeth_band3(const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst,
                                                   std::size_t dst_pitch, const std::uint8_t* above,
                                                   std::size_t width) {
  unpaeth_band4_avx2<3>(src, src_pitch, dst, dst_pitch, above, width);
}
__attribute__((target("avx2"))) void unpaeth_band4(const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst,
                                                   std::size_t dst_pitch, const std::uint8_t* above,
                                                   std::size_t width) {
  unpaeth_band4_avx2<4>(src, src_pitch, dst, dst_pitch, above, width);
}

// The same with eight rows in one AVX-512 register (eight slots), for processors that have it:
// twice the rows per step of the same chain. `width` >= 8.
// GCC 12 warns that the "undefined" register its own AVX-512 headers pass to the permute and the
// narrowing (_mm512_undefined_epi32) may be used uninitialised: a false positive, silenced here only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
template <std::size_t BPP>
__attribute__((target("avx512f,avx512bw"), always_inline)) inline void unpaeth_band8_avx512(
    const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst, std::size_t dst_pitch, const std::uint8_t* above,
    std::size_t width) {
  static_assert(BPP == 3 || BPP == 4, "a pixel per slot of four lanes");
  constexpr int R = 8;
  const std::uint8_t* in[R];
  std::uint8_t* out[R];
  for (int k = 0; k < R; ++k) in[k] = src + k * src_pitch, out[k] = dst + k * dst_pitch;
  for (int k = 0; k + 1 < R; ++k)
    unpaeth_range<BPP>(in[k], out[k], k == 0 ? above : out[k - 1], 0, static_cast<std::size_t>(R - 1 - k));
  alignas(32) std::int32_t w1[R], w2[R], offsets_of[R];
  for (int k = 0; k < R; ++k) {
    w1[k] = R - 2 - k >= 0 ? band_pixel<BPP>(out[k] + (R - 2 - k) * BPP) : 0;
    w2[k] = R - 3 - k >= 0 ? band_pixel<BPP>(out[k] + (R - 3 - k) * BPP) : 0;
    offsets_of[k] = static_cast<std::int32_t>(k * (src_pitch - BPP));
  }
  __m512i prev = _mm512_cvtepu8_epi16(_mm256_load_si256(reinterpret_cast<const __m256i*>(w1)));
  __m512i prev2 = _mm512_cvtepu8_epi16(_mm256_load_si256(reinterpret_cast<const __m256i*>(w2)));
  const __m256i offsets = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets_of));
  const __m512i up_a_slot = _mm512_setr_epi64(0, 0, 1, 2, 3, 4, 5, 6);
  const __m512i low_byte = _mm512_set1_epi16(0xff);
  alignas(32) std::uint32_t v[R];
  for (std::size_t t = R - 1; t < width; ++t) {
    const __m512i x =
        _mm512_cvtepu8_epi16(_mm256_i32gather_epi32(reinterpret_cast<const int*>(src + t * BPP), offsets, 1));
    std::int32_t up, up_left;
    std::memcpy(&up, above + t * BPP, 4);
    std::memcpy(&up_left, above + (t - 1) * BPP, 4);
    const __m512i b = _mm512_mask_blend_epi64(0x01, _mm512_permutexvar_epi64(up_a_slot, prev),
                                              _mm512_cvtepu8_epi16(_mm256_castsi128_si256(_mm_cvtsi32_si128(up))));
    const __m512i c = _mm512_mask_blend_epi64(0x01, _mm512_permutexvar_epi64(up_a_slot, prev2),
                                              _mm512_cvtepu8_epi16(_mm256_castsi128_si256(_mm_cvtsi32_si128(up_left))));
    const __m512i a = prev;
    const __m512i b_c = _mm512_sub_epi16(b, c), a_c = _mm512_sub_epi16(a, c);
    const __m512i pa = _mm512_abs_epi16(b_c), pb = _mm512_abs_epi16(a_c), pc = _mm512_abs_epi16(_mm512_add_epi16(b_c, a_c));
    // a where pa <= pb and pa <= pc; else b where pb <= pc; else c.
    const __mmask32 not_a = _mm512_cmpgt_epi16_mask(pa, pb) | _mm512_cmpgt_epi16_mask(pa, pc);
    const __m512i b_or_c = _mm512_mask_blend_epi16(_mm512_cmpgt_epi16_mask(pb, pc), b, c);
    const __m512i predictor = _mm512_mask_blend_epi16(not_a, a, b_or_c);
    const __m512i result = _mm512_and_si512(_mm512_add_epi16(x, predictor), low_byte);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), _mm512_cvtepi16_epi8(result));
    for (int k = 0; k < R; ++k) std::memcpy(out[k] + (t - k) * BPP, &v[k], BPP);
    prev2 = prev;
    prev = result;
  }
  for (int k = 1; k < R; ++k)
    unpaeth_range<BPP>(in[k], out[k], out[k - 1], width - static_cast<std::size_t>(k), width);
}

__attribute__((target("avx512f,avx512bw"))) void unpaeth_band8_3(const std::uint8_t* src, std::size_t src_pitch,
                                                                 std::uint8_t* dst, std::size_t dst_pitch,
                                                                 const std::uint8_t* above, std::size_t width) {
  unpaeth_band8_avx512<3>(src, src_pitch, dst, dst_pitch, above, width);
}
__attribute__((target("avx512f,avx512bw"))) void unpaeth_band8_4(const std::uint8_t* src, std::size_t src_pitch,
                                                                 std::uint8_t* dst, std::size_t dst_pitch,
                                                                 const std::uint8_t* above, std::size_t width) {
  unpaeth_band8_avx512<4>(src, src_pitch, dst, dst_pitch, above, width);
}
#pragma GCC diagnostic pop
#endif

std::atomic<int> paeth_bands_limit{2};

// The widest bands this processor runs, at most what a test allowed: 0 none, 1 four rows (AVX2),
// 2 eight rows (AVX-512).
int paeth_bands() { return std::min(simd_level(), paeth_bands_limit.load(std::memory_order_relaxed)); }

}  // namespace

int simd_level() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const int level = __builtin_cpu_supports("avx512bw") ? 2 : __builtin_cpu_supports("avx2") ? 1 : 0;
  return level;
#else
  return 0;
#endif
}

int limit_paeth_bands(int level) {
  paeth_bands_limit.store(level, std::memory_order_relaxed);
  return simd_level();
}

bool unfilter(std::uint8_t* raw, std::size_t stride, std::size_t bpp, std::size_t width, std::size_t height, bool swap,
              cv::Mat& image) {
  // Each row undone against the one above (zeros above the first). 8-bit rows go from `raw`
  // straight into the image's rows (a copy afterwards was 3% of a 512x256 render's time, perf);
  // 16-bit rows are undone in place and then copied with their bytes swapped where the machine
  // is little-endian (PNG's samples are big-endian).
  auto source_row = [&](std::size_t y) { return raw + y * (stride + 1) + 1; };
  auto output_row = [&](std::size_t y) { return swap ? source_row(y) : image.ptr<std::uint8_t>(static_cast<int>(y)); };
  // Zeros over the first row, with bytes to spare: unpaeth_band reads four bytes a pixel, one
  // past the last pixel of an RGB row (where an image row has the next row's first byte).
  const std::vector<std::uint8_t> zero(stride + 4, 0);
  const std::uint8_t* above = zero.data();
  // Runs of eight or four Paeth rows of 8-bit RGB or RGBA (most rows of most photographs' PNGs) as
  // bands, where the processor has the registers for them.
  const int bands = !swap && (bpp == 3 || bpp == 4) ? paeth_bands() : 0;
  auto paeth_run = [&](std::size_t y, std::size_t n) {  // rows y .. y + n - 1 all Paeth
    if (y + n > height || width < n) return false;
    for (std::size_t k = 0; k < n; ++k)
      if (raw[(y + k) * (stride + 1)] != 4) return false;
    return true;
  };
  for (std::size_t y = 0; y < height; ++y) {
    const std::uint8_t* src = source_row(y);
    std::uint8_t* dst = output_row(y);
    const std::uint8_t type = src[-1];
#if defined(__x86_64__) && defined(__GNUC__)
    if (type == 4 && bands >= 2 && paeth_run(y, 8)) {
      (bpp == 3 ? unpaeth_band8_3 : unpaeth_band8_4)(src, stride + 1, dst, image.step[0], above, width);
      y += 7;
      above = output_row(y);
      continue;
    }
    if (type == 4 && bands >= 1 && paeth_run(y, 4)) {
      (bpp == 3 ? unpaeth_band3 : unpaeth_band4)(src, stride + 1, dst, image.step[0], above, width);
      y += 3;
      above = output_row(y);
      continue;
    }
#endif
    switch (type) {
      case 0:
        if (dst != src) std::memcpy(dst, src, stride);
        break;
      case 1:
        for (std::size_t i = 0; i < bpp && i < stride; ++i) dst[i] = src[i];
        for (std::size_t i = bpp; i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + dst[i - bpp]);
        break;
      case 2:
        for (std::size_t i = 0; i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + above[i]);
        break;
      case 3:
        for (std::size_t i = 0; i < bpp && i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + (above[i] >> 1));
        for (std::size_t i = bpp; i < stride; ++i)
          dst[i] = static_cast<std::uint8_t>(src[i] + ((dst[i - bpp] + above[i]) >> 1));
        break;
      case 4:
        switch (bpp) {
          case 1: unpaeth<1>(src, dst, above, stride); break;
          case 2: unpaeth<2>(src, dst, above, stride); break;
          case 3: unpaeth<3>(src, dst, above, stride); break;
          case 4: unpaeth<4>(src, dst, above, stride); break;
          case 6: unpaeth<6>(src, dst, above, stride); break;
          default: unpaeth<8>(src, dst, above, stride); break;  // 16-bit RGBA
        }
        break;
      default:
        return false;
    }
    above = dst;
  }
  if (swap)
    for (std::size_t y = 0; y < height; ++y)
      copy_swapping_16_bit(source_row(y), image.ptr<std::uint8_t>(static_cast<int>(y)), stride);
  return true;
}

}  // namespace raindrop::png
