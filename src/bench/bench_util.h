#pragma once
// Shared helpers of the benchmark programs: timing, statistics, machine description.
#include <dlfcn.h>
#include <stdlib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace raindrop::bench {

inline double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// A new, private scratch folder under the system's temporary folder (mkdtemp: a fresh random
// name, created here, mode 0700). A name made from the process id could already exist (as a
// link to somewhere else, say) and would then be written through.
inline std::filesystem::path make_scratch_dir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "raindrop-bench-XXXXXX").string();
  if (!::mkdtemp(pattern.data()))
    throw std::runtime_error("cannot create a scratch folder in " + std::filesystem::temp_directory_path().string() +
                             " (" + std::strerror(errno) + ")");
  return pattern;
}

inline double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / v.size();
}

// The widest vector instructions this process is told it may use (x86-64), and whether
// libraindrop_hide_avx512.so hides some: the kernels ONNX Runtime, Embree and the blur choose.
inline std::string vector_instructions() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  std::string isa = __builtin_cpu_supports("avx512f") ? "AVX-512" : __builtin_cpu_supports("avx2") ? "AVX2" : "SSE";
  if (const auto* hidden = static_cast<const int*>(::dlsym(RTLD_DEFAULT, "raindrop_hide_avx512_active")); hidden && *hidden)
    isa += " (AVX-512 and VNNI hidden by libraindrop_hide_avx512.so)";
  return isa;
#else
  return "not x86";
#endif
}

// "AMD EPYC, 2 hardware threads, AVX2" from /proc/cpuinfo and the instructions seen.
inline std::string machine_description() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, model = "unknown CPU";
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  }
  return model + ", " + std::to_string(std::thread::hardware_concurrency()) + " hardware threads, " +
         vector_instructions();
}

}  // namespace raindrop::bench
