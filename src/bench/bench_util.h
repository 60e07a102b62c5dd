#pragma once
// Shared helpers of the benchmark programs: timing, statistics, machine description.
#include <dlfcn.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

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

namespace scratch_detail {
// The scratch folders a signal must remove: fixed storage, since the handler may only use what
// is safe in a signal handler (fork, execve, waitpid, signal, raise).
inline constexpr int kSlots = 8;
inline char paths[kSlots][4096];
inline volatile sig_atomic_t used[kSlots];

// Ctrl-C, a kill or a closed terminal: the scratch folders (frames and models' outputs, tens of
// megabytes) go with the run, removed by rm in a child process, and the signal then ends the
// bench as it would have.
extern "C" inline void remove_and_reraise(int sig) {
  for (int i = 0; i < kSlots; ++i) {
    if (!used[i]) continue;
    const pid_t pid = ::fork();
    if (pid == 0) {
      char rm[] = "rm", rf[] = "-rf", dashes[] = "--";
      char* argv[] = {rm, rf, dashes, paths[i], nullptr};
      char* envp[] = {nullptr};
      ::execve("/bin/rm", argv, envp);
      ::_exit(127);
    }
    if (pid > 0) ::waitpid(pid, nullptr, 0);
  }
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

inline void install_once() {
  static const bool installed = [] {
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction old {};
      if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_DFL) {  // an ignored signal stays ignored
        struct sigaction sa {};
        sa.sa_handler = remove_and_reraise;
        sigemptyset(&sa.sa_mask);
        ::sigaction(sig, &sa, nullptr);
      }
    }
    return true;
  }();
  (void)installed;
}
}  // namespace scratch_detail

// A new, private scratch folder under the system's temporary folder (mkdtemp: a fresh random
// name, created here, mode 0700). A name made from the process id could already exist (as a
// link to somewhere else, say) and would then be written through. Removed by the caller, or
// by the signal that ends the bench (scratch_detail).
inline std::filesystem::path make_scratch_dir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "raindrop-bench-XXXXXX").string();
  if (!::mkdtemp(pattern.data()))
    throw std::runtime_error("cannot create a scratch folder in " + std::filesystem::temp_directory_path().string() +
                             " (" + std::strerror(errno) + ")");
  scratch_detail::install_once();
  for (int i = 0; i < scratch_detail::kSlots; ++i) {
    if (!scratch_detail::used[i] && pattern.size() < sizeof scratch_detail::paths[i]) {
      std::memcpy(scratch_detail::paths[i], pattern.c_str(), pattern.size() + 1);
      scratch_detail::used[i] = 1;
      break;
    }
  }
  return pattern;
}

// After the caller removed it: a signal no longer needs to.
inline void forget_scratch_dir(const std::filesystem::path& dir) {
  for (int i = 0; i < scratch_detail::kSlots; ++i)
    if (scratch_detail::used[i] && dir.string() == scratch_detail::paths[i]) scratch_detail::used[i] = 0;
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
