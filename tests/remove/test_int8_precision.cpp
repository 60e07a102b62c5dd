// int8 model folders give the same output on a CPU without VNNI as on one with it
// (include/raindrop/remove/int8_precision.h). Without VNNI, ONNX Runtime's fast uint8 x int8
// products saturate at 16 bits and changed the detector's masks; raindrop-remove then asks for
// its exact kernels. No machine has both kinds of CPU, so the program runs twice: natively, and
// as on a Haswell-class CPU (AVX2, no VNNI, no AVX-512), down ONNX Runtime's non-VNNI code paths.
// The second run uses the build's libraindrop_hide_avx512.so (src/bench/hide_avx512.cpp: cpuid
// answered without those features, native speed) where this CPU and kernel can trap cpuid, and
// otherwise QEMU's user-mode emulator (`qemu-x86_64 -cpu Haswell`, about 50 s; Debian: qemu-user,
// which scripts/test.sh installs). Skips with a message where neither can run.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>

#include "raindrop/remove/int8_precision.h"
#include "raindrop/remove/model_paths.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

// The committed int8 folder of the default model (models/<DEFAULT>-int8), or the first int8 one.
fs::path int8_models() {
  const std::string default_name = raindrop::removal::read_default_config(source_dir() / "models").value_or("");
  fs::path first;
  for (const auto& dir : trained_models()) {
    const std::string name = dir.filename().string();
    if (name.size() < 5 || name.compare(name.size() - 5, 5, "-int8") != 0) continue;
    if (name == default_name + "-int8") return dir;
    if (first.empty()) first = dir;
  }
  return first;
}

TEST(Int8Precision, OnlyX86CpusWithoutVnniNeedTheExactKernels) {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  const bool vnni = __builtin_cpu_supports("avx512vnni") || __builtin_cpu_supports("avxvnni");
  EXPECT_EQ(raindrop::removal::int8_products_saturate(), !vnni);
  EXPECT_EQ(std::string(raindrop::removal::int8_kernels_description()),
            vnni ? "VNNI" : "exact uint8 kernels (this CPU has no VNNI)");
#else
  EXPECT_FALSE(raindrop::removal::int8_products_saturate());
#endif
}

// How to run raindrop-remove as on a CPU without VNNI: `env`, then `program`, then
// `program_args` and the arguments; `how` says which. Returns why it cannot ("" where it can);
// a failure of the check itself is a test failure (ADD_FAILURE) and is returned too.
struct NoVnniRun {
  std::vector<std::string> env;
  fs::path program;
  std::vector<std::string> program_args;
  std::string how;
};

std::string no_vnni_run(const fs::path& cwd, NoVnniRun* nv) {
  nv->program = remove_bin();
  RunResult r;
#ifdef RAINDROP_HIDE_AVX512_LIB
  // (In a sanitizer build the sanitizer's runtime must otherwise be the first library loaded.)
  const char* asan = std::getenv("ASAN_OPTIONS");
  nv->env = {std::string("LD_PRELOAD=") + RAINDROP_HIDE_AVX512_LIB,
             std::string("ASAN_OPTIONS=") + (asan && *asan ? std::string(asan) + ":" : "") + "verify_asan_link_order=0"};
  r = run_command(remove_bin(), {"--version"}, cwd, nv->env);
  if (r.code == 0) nv->how = "libraindrop_hide_avx512.so";
  else if (r.code != 3 || r.err.find("cannot trap cpuid") == std::string::npos) {
    ADD_FAILURE() << r.describe();
    return "the cpuid trap failed";
  }
#endif
  if (nv->how.empty()) {
#if defined(__SANITIZE_ADDRESS__)
    return "this CPU cannot trap cpuid for libraindrop_hide_avx512.so, and an AddressSanitizer build "
           "cannot run under qemu-x86_64 (its shadow memory)";
#endif
    nv->env.clear();
    nv->program = testsupport::find_on_path("qemu-x86_64");
    if (nv->program.empty())
      return "this CPU cannot trap cpuid for libraindrop_hide_avx512.so, and qemu-x86_64 is not on the PATH "
             "(Debian: apt-get install qemu-user; scripts/test.sh installs it)";
    nv->program_args = {"-cpu", "Haswell", remove_bin().string()};
    nv->how = "qemu-x86_64 -cpu Haswell";
    nv->program_args.push_back("--version");
    r = run_command(nv->program, nv->program_args, cwd);
    nv->program_args.pop_back();
    if (r.code != 0) {
      ADD_FAILURE() << r.describe();
      return "qemu-x86_64 failed";
    }
  }
  // The program sees a CPU without VNNI.
  if (r.out.find("int8 models: exact uint8 kernels (this CPU has no VNNI)") == std::string::npos) {
    ADD_FAILURE() << nv->how << "\n" << r.describe();
    return "the program still sees VNNI";
  }
  return "";
}

TEST(Int8Precision, AnInt8FolderGivesTheSameOutputOnACpuWithoutVnni) {
#if !defined(__x86_64__)
  GTEST_SKIP() << "x86-64 only (the saturating products are x86's)";
#endif
  REQUIRE_RENDER();
  const fs::path models = int8_models();
  if (models.empty()) GTEST_SKIP() << "no int8 model folder in " << (source_dir() / "models");
  TempDir tmp;
  // Two demo frames at the models' training size (512x256: working scale 1). The large-drop
  // pass is left out: its graphs are float, whose sums may differ in their last bits between
  // AVX-512 and AVX2 kernels, and this test is about the int8 products.
  RunResult r = run_command(RAINDROP_RENDER_BIN, {"--demo", "--size", "512x256", "--seed", "7", "--out", "set", "-q", "-j", "1"},
                            tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();

  NoVnniRun nv;
  if (const std::string skip = no_vnni_run(tmp.path(), &nv); !skip.empty()) GTEST_SKIP() << skip;
  std::ifstream info(models / "export.json");
  const bool kept_float = std::string(std::istreambuf_iterator<char>(info), {}).find("\"kept_float\"") != std::string::npos;
  const std::vector<std::string> common{"--models", models.string(), "--no-large-drops", "-q", "-j", "2"};
  auto args = [&](const std::string& tag) {
    std::vector<std::string> a{"set/rainy", "out-" + tag, "--mask-dir", "mask-" + tag};
    a.insert(a.end(), common.begin(), common.end());
    return a;
  };
  r = run_remove(args("native"), tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  for (const auto& a : args("haswell")) nv.program_args.push_back(a);
  r = run_command(nv.program, nv.program_args, tmp.path(), nv.env);
  ASSERT_EQ(r.code, 0) << nv.how << "\n" << r.describe();

  int compared = 0;
  for (const auto& e : fs::directory_iterator(tmp / "set/rainy")) {
    const std::string n = e.path().filename().string();
    for (const std::string kind : {"out", "mask"}) {
      std::string why;
      const auto a = read_image(tmp / (kind + "-native") / n, &why);
      ASSERT_TRUE(a.has_value()) << why;
      const auto b = read_image(tmp / (kind + "-haswell") / n, &why);
      ASSERT_TRUE(b.has_value()) << why;
      ASSERT_EQ(a->pixels.size(), b->pixels.size());
      // The masks come from the int8 detector alone: the same bits. The output passes the RFN,
      // which the default's int8 copy keeps in float (docs/RESULTS.md 4.60), and float kernels
      // may round a last bit differently on AVX-512 and AVX2: within a level there.
      const double diff = cv::norm(a->pixels, b->pixels, cv::NORM_INF);
      const double allowed = kind == "out" && kept_float ? 1.0 : 0.0;
      EXPECT_LE(diff, allowed) << models.filename() << " " << kind << " of " << n
                               << " differs between this CPU and one without VNNI (" << nv.how << "; max " << diff << " levels)";
      ++compared;
    }
  }
  EXPECT_EQ(compared, 4);
}

// models/DEFAULT's int8 copy ("vnni NAME") is what raindrop-remove loads without --models on a
// CPU with VNNI, and the float default on one without: int8 there is slower (docs/RESULTS.md
// 3.10, 4.60). The models line says which, and why.
TEST(Int8Precision, TheDefaultIsItsInt8CopyOnlyWithVnni) {
#if !defined(__x86_64__)
  GTEST_SKIP() << "x86-64 only";
#endif
  const auto defaults = raindrop::removal::read_default(source_dir() / "models");
  if (!defaults || !defaults->int8_fast || !fs::is_regular_file(source_dir() / "models" / *defaults->int8_fast / "rdn.onnx"))
    GTEST_SKIP() << "models/DEFAULT names no committed int8 copy";
  const std::string& first = defaults->name;
  const std::string& int8_name = *defaults->int8_fast;
  TempDir tmp;
  write_image(tmp / "in.png", make_image(96, 64, 3));
  const std::vector<std::string> args{"in.png", "out.png", "--time", "-j", "1", "--no-large-drops"};
  const std::string float_line = "models/" + first + "' (config", int8_line = "models/" + int8_name + "' (config";
  RunResult r = run_remove(args, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const bool vnni_here = raindrop::removal::int8_runs_fast();
  EXPECT_NE(r.err.find(vnni_here ? int8_line : float_line), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find("this CPU has VNNI)") != std::string::npos, vnni_here) << r.describe();
  NoVnniRun nv;
  if (const std::string skip = no_vnni_run(tmp.path(), &nv); !skip.empty()) GTEST_SKIP() << skip;
  std::vector<std::string> a = nv.program_args;
  a.insert(a.end(), args.begin(), args.end());
  r = run_command(nv.program, a, tmp.path(), nv.env);
  ASSERT_EQ(r.code, 0) << nv.how << "\n" << r.describe();
  EXPECT_NE(r.err.find(float_line), std::string::npos) << nv.how << "\n" << r.describe();
  EXPECT_EQ(r.err.find("int8"), std::string::npos) << nv.how << "\n" << r.describe();
}

}  // namespace
}  // namespace removetest
