// libraindrop_hide_avx512.so: run any program as if this x86-64 CPU had no AVX-512 and no VNNI,
// natively, to measure and test the code paths such CPUs take (AMD Zen 2/3, Intel before Ice
// Lake server and Alder Lake):
//
//   LD_PRELOAD=build/libraindrop_hide_avx512.so build/raindrop-bench remove ...
//
// Libraries choose their kernels by asking the `cpuid` instruction (ONNX Runtime's MLAS, Embree,
// GCC's __builtin_cpu_supports). Linux can make `cpuid` trap (arch_prctl ARCH_SET_CPUID, where the
// CPU or hypervisor offers "cpuid_fault"); this library turns that on for the process and answers
// each trapped `cpuid` with the real one's answer less the AVX-512, VNNI and AMX bits. Unlike an
// emulator (qemu-x86_64 -cpu Haswell) the code runs at full speed, so its time means something;
// unlike an emulator it cannot stop code that uses AVX-512 without asking, so it is for speed and
// kernel choice, not for proving a binary runs on an older CPU.
//
// What it cannot hide, or where it fails:
// - glibc's own string functions chose their variants before this library was loaded, and a
//   shared library that asks `cpuid` in its own load-time constructor may run before this one
//   (ONNX Runtime 1.31, Embree and GCC's __builtin_cpu_supports in an executable ask later);
// - a program that installs its own SIGSEGV handler (Python with PYTHONFAULTHANDLER set, for
//   one) replaces this one, and a thread that blocks SIGSEGV dies at its first `cpuid`;
// - under AddressSanitizer the sanitizer's runtime must come first: run with
//   ASAN_OPTIONS=verify_asan_link_order=0.
// Where cpuid cannot trap, the process stops at start (exit 3) with a one-line message rather
// than run with nothing hidden and give a misleading measurement. A SIGSEGV that is not a
// trapped `cpuid` (a real fault, or one sent with kill) ends the process as it would without
// this library.
#include <asm/prctl.h>
#include <cpuid.h>
#include <signal.h>
#include <sys/syscall.h>
#include <ucontext.h>
#include <unistd.h>

#include <cstring>

// Non-zero in a process this library was loaded into (raindrop-bench says so in its machine line).
extern "C" {
__attribute__((visibility("default"))) int raindrop_hide_avx512_active = 0;
}

namespace {

long set_cpuid_enabled(int enabled) { return syscall(SYS_arch_prctl, ARCH_SET_CPUID, enabled); }

void hide(unsigned leaf, unsigned subleaf, unsigned* a, unsigned* b, unsigned* c, unsigned* d) {
  if (leaf == 7 && subleaf == 0) {
    // EBX: AVX512 F, DQ, IFMA, PF, ER, CD, BW, VL. ECX: VBMI, VBMI2, VNNI, BITALG, VPOPCNTDQ.
    // EDX: 4VNNIW, 4FMAPS, VP2INTERSECT, AMX-BF16, AVX512-FP16, AMX-TILE, AMX-INT8.
    *b &= ~((1u << 16) | (1u << 17) | (1u << 21) | (1u << 26) | (1u << 27) | (1u << 28) | (1u << 30) | (1u << 31));
    *c &= ~((1u << 1) | (1u << 6) | (1u << 11) | (1u << 12) | (1u << 14));
    *d &= ~((1u << 2) | (1u << 3) | (1u << 8) | (1u << 22) | (1u << 23) | (1u << 24) | (1u << 25));
  } else if (leaf == 7 && subleaf == 1) {
    // EAX: AVX-VNNI, AVX512-BF16, AMX-FP16. EDX: AVX-VNNI-INT8, AVX-NE-CONVERT, AMX-COMPLEX,
    // AVX-VNNI-INT16, AVX10.
    *a &= ~((1u << 4) | (1u << 5) | (1u << 21));
    *d &= ~((1u << 4) | (1u << 5) | (1u << 8) | (1u << 10) | (1u << 19));
  }
}

void on_sigsegv(int sig, siginfo_t* info, void* context) {
  auto* uc = static_cast<ucontext_t*>(context);
  greg_t* r = uc->uc_mcontext.gregs;
  // A trapped cpuid arrives from the kernel (SI_KERNEL) with RIP on the instruction, 0F A2.
  const bool from_kernel = info->si_code == SI_KERNEL;
  const auto* ip = reinterpret_cast<const unsigned char*>(r[REG_RIP]);
  if (!from_kernel || ip[0] != 0x0f || ip[1] != 0xa2) {
    signal(sig, SIG_DFL);
    if (info->si_code <= 0) raise(sig);  // sent by a process (kill, raise): delivered as without us
    return;  // a fault: the instruction runs again and now kills the process
  }
  const auto leaf = static_cast<unsigned>(r[REG_RAX]), subleaf = static_cast<unsigned>(r[REG_RCX]);
  unsigned a, b, c, d;
  set_cpuid_enabled(1);
  __cpuid_count(leaf, subleaf, a, b, c, d);
  set_cpuid_enabled(0);
  hide(leaf, subleaf, &a, &b, &c, &d);
  r[REG_RAX] = a;
  r[REG_RBX] = b;
  r[REG_RCX] = c;
  r[REG_RDX] = d;
  r[REG_RIP] += 2;  // past the two-byte cpuid
}

}  // namespace

__attribute__((constructor)) static void hide_avx512_start(void) {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_sigaction = on_sigsegv;
  sa.sa_flags = SA_SIGINFO;
  sigemptyset(&sa.sa_mask);
  if (sigaction(SIGSEGV, &sa, nullptr) != 0 || set_cpuid_enabled(0) != 0) {
    static const char msg[] =
        "libraindrop_hide_avx512.so: this CPU or kernel cannot trap cpuid (arch_prctl ARCH_SET_CPUID failed; "
        "no \"cpuid_fault\" in /proc/cpuinfo), so nothing could be hidden: stopping\n";
    (void)!write(2, msg, sizeof msg - 1);
    _exit(3);
  }
  raindrop_hide_avx512_active = 1;
}
