// ONNX Runtime's official Linux builds collect usage telemetry: with it on, creating the
// environment writes a device id and an event database under ~/.cache/Microsoft and a session
// file in $TMPDIR, and uploads events where a network is reachable (raindrop/remove/session.h).
// raindrop turns it off. These tests run with ORT_DISABLE_TELEMETRY unset and HOME, TMPDIR and
// XDG_CACHE_HOME pointing into empty folders, and check that those stay empty, once through the
// program and once through the library alone (for programs that link it without our main()).
//
// They cannot show that nothing is uploaded (no network here), but with telemetry on the files
// appear on every run, so their absence is what shows it off. (Checked by hand: without the
// call in ort_env() and main(), both tests fail, listing the deviceid, the database and .ses.)
#include "remove_test_util.h"
#include "raindrop/remove/remover.h"

namespace removetest {
namespace {

// Every file and folder under `dir`, sorted, one per line ("" when empty), leaving out the
// test harness's own _logs folder (run_captured keeps the child's output there).
std::string listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string name = fs::relative(e.path(), dir).string();
    if (name.rfind("_logs", 0) != 0) names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  std::string out;
  for (const auto& n : names) out += n + "\n";
  return out;
}

// "env -u ORT_DISABLE_TELEMETRY HOME=... TMPDIR=... XDG_CACHE_HOME=... ", with empty folders
// home/, tmp/ and cache/ made in `tmp`.
std::string private_places(const TempDir& tmp) {
  for (const char* d : {"home", "tmp", "cache"}) fs::create_directories(tmp / d);
  return "env -u ORT_DISABLE_TELEMETRY -u RAINDROP_MODELS HOME=" + shell_quote((tmp / "home").string()) +
         " TMPDIR=" + shell_quote((tmp / "tmp").string()) + " XDG_CACHE_HOME=" + shell_quote((tmp / "cache").string()) +
         " ";
}

void expect_untouched(const TempDir& tmp) {
  for (const char* d : {"home", "tmp", "cache"})
    EXPECT_EQ(listing(tmp / d), "") << "ONNX Runtime wrote into " << d << "/ (its telemetry is on)";
}

TEST(OrtTelemetry, RaindropRemoveWritesOnlyItsOutput) {
  TempDir tmp;
  fs::create_directories(tmp / "work");
  write_image(tmp / "work" / "in.png", make_image(96, 64, 1));
  const std::vector<std::string> args = {"in.png", "out.png", "-j", "1", "--models", smoke_models().string()};
  const RunResult r = testsupport::run_captured(remove_bin(), args, tmp / "work", private_places(tmp));
  ASSERT_EQ(r.code, 0) << r.describe();
  expect_untouched(tmp);
  EXPECT_EQ(listing(tmp / "work"), "in.png\nout.png\n");
}

TEST(OrtTelemetry, RaindropRemoveVersionSaysSo) {
  TempDir tmp;
  const RunResult r = testsupport::run_captured(remove_bin(), {"--version"}, tmp.path(), private_places(tmp));
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("telemetry off (ORT_DISABLE_TELEMETRY=1)"), std::string::npos) << r.describe();
  // A value the user set is theirs, and --version says what it does, read as ONNX Runtime reads
  // it. (Only --version: nothing starts ONNX Runtime here, so an opted-in run sends nothing.)
  for (const auto& [value, state] : std::vector<std::pair<std::string, std::string>>{
           {"0", "telemetry ON (ORT_DISABLE_TELEMETRY=0 in the environment)"},
           {"off", "telemetry ON (ORT_DISABLE_TELEMETRY=off in the environment)"},
           {"TRUE", "telemetry off (ORT_DISABLE_TELEMETRY=TRUE)"}}) {
    const RunResult in = testsupport::run_captured(remove_bin(), {"--version"}, tmp.path(), "ORT_DISABLE_TELEMETRY=" + value + " ");
    ASSERT_EQ(in.code, 0) << in.describe();
    EXPECT_NE(in.out.find(state), std::string::npos) << in.describe();
  }
}

// The library on its own, in a process whose main() did not turn telemetry off: the test runs
// itself as a child (RAINDROP_TELEMETRY_CHILD set), which loads the models and removes drops
// from one image, and checks the child's private folders afterwards.
TEST(OrtTelemetry, TheLibraryAloneTurnsItOff) {
  if (std::getenv("RAINDROP_TELEMETRY_CHILD")) {
    raindrop::removal::Remover remover(smoke_models());
    const raindrop::removal::RemoveResult r = remover.run(make_image(96, 64, 2), {});
    EXPECT_EQ(r.image.size(), cv::Size(96, 64));
    return;
  }
  TempDir tmp;
  const fs::path self = fs::read_symlink("/proc/self/exe");
  const RunResult r = testsupport::run_captured(self, {"--gtest_filter=OrtTelemetry.TheLibraryAloneTurnsItOff"},
                                                tmp.path(), private_places(tmp) + "RAINDROP_TELEMETRY_CHILD=1 ");
  ASSERT_EQ(r.code, 0) << r.describe();
  ASSERT_NE(r.out.find("[  PASSED  ] 1 test"), std::string::npos) << r.describe();
  expect_untouched(tmp);
}

}  // namespace
}  // namespace removetest
