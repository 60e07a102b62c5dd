// A data set does not depend on the CPU it was rendered on: raindrop-render writes the same bytes
// on a CPU without AVX-512 as on this one. Embree and the disk blur (blur.cpp: AVX-512 and AVX
// paths, chosen at run time) take other paths there; the bytes must not change. The program runs natively and under QEMU's user-mode
// emulator with a Haswell CPU (AVX2, no AVX-512: `qemu-x86_64 -cpu Haswell`), which sends Embree
// and every library down their AVX2 paths. Needs qemu-x86_64 (Debian: qemu-user, which
// scripts/test.sh installs); skips with a message without it. Where this CPU has no AVX-512
// either, both runs take the same paths and the test still holds the program to determinism.
#include <gtest/gtest.h>

#include "cli_test_util.h"

namespace clitest {
namespace {

TEST(RenderAnyCpu, TheSameBytesOnACpuWithoutAvx512) {
#if !defined(__x86_64__)
  GTEST_SKIP() << "x86-64 only";
#endif
#if defined(__SANITIZE_ADDRESS__)
  // AddressSanitizer maps terabytes of shadow memory at start, which QEMU's user-mode emulator
  // cannot give it: the emulated program is killed (scripts/test-sanitizers.sh).
  GTEST_SKIP() << "an AddressSanitizer build cannot run under qemu-x86_64";
#endif
  const fs::path qemu = testsupport::find_on_path("qemu-x86_64");
  if (qemu.empty()) GTEST_SKIP() << "qemu-x86_64 not on the PATH (Debian: apt-get install qemu-user; scripts/test.sh installs it)";
  TempDir tmp;
  // The default preset (sharp drops, total internal reflection), and two that add the thin lens,
  // the veil, lifted highlights, sensor noise and outlines (about 10 s emulated in all).
  for (const std::string scene : {"paper", "full-physics", "windshield-night"}) {
    SCOPED_TRACE(scene);
    const std::vector<std::string> args{"--demo", "--scene", scene, "--size", "512x256", "--seed", "7", "-q", "-j", "2", "--out"};
    auto native = args, emulated = std::vector<std::string>{"-cpu", "Haswell", render_bin().string()};
    native.push_back("native-" + scene);
    emulated.insert(emulated.end(), args.begin(), args.end());
    emulated.push_back("haswell-" + scene);
    RunResult r = run_render(native, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    r = RunResult{testsupport::run_captured(qemu, emulated, tmp.path())};
    ASSERT_EQ(r.code, 0) << r.describe();
    int compared = 0;
    for (const std::string kind : {"rainy", "clean", "mask"}) {
      for (const auto& e : fs::directory_iterator(tmp / ("native-" + scene) / kind)) {
        const fs::path other = tmp / ("haswell-" + scene) / kind / e.path().filename();
        ASSERT_TRUE(fs::exists(other)) << other;
        EXPECT_TRUE(read_file(e.path()) == read_file(other))
            << scene << " " << kind << "/" << e.path().filename().string() << " differs on the emulated CPU";
        ++compared;
      }
    }
    EXPECT_EQ(compared, 6);
  }
}

}  // namespace
}  // namespace clitest
