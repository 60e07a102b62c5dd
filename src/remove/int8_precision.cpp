#include "raindrop/remove/int8_precision.h"

namespace raindrop::removal {

bool int8_products_saturate() {
#if defined(__x86_64__) || defined(__i386__)
  // libgcc's CPU model also checks that the OS saves the registers the feature needs (XCR0), as
  // ONNX Runtime's own dispatch does, so "supported" here means usable.
  __builtin_cpu_init();
  const bool vnni = __builtin_cpu_supports("avx512vnni") || __builtin_cpu_supports("avxvnni");
  return !vnni;
#else
  return false;
#endif
}

bool int8_runs_fast() {
#if defined(__x86_64__) || defined(__i386__)
  return !int8_products_saturate();
#else
  return false;
#endif
}

const char* int8_kernels_description() {
#if defined(__x86_64__) || defined(__i386__)
  return int8_products_saturate() ? "exact uint8 kernels (this CPU has no VNNI)" : "VNNI";
#else
  return "32-bit sums";
#endif
}

}  // namespace raindrop::removal
