// model_paths.h: where raindrop-remove finds its models, and the default configuration.
#include "raindrop/common/error.h"
#include "raindrop/remove/int8_precision.h"
#include "raindrop/remove/model_paths.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

class ModelSearchTest : public ::testing::Test {
 protected:
  void make_models(const fs::path& dir) {
    for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) write_file(dir / f, "x");
  }
  TempDir tmp;
};

TEST_F(ModelSearchTest, ExplicitFolderWinsOverEverything) {
  ModelSearch s;
  s.explicit_dir = tmp / "mine";
  s.env_dir = tmp / "env";
  make_models(tmp / "env");
  EXPECT_EQ(find_models(s), tmp / "mine");
}

TEST_F(ModelSearchTest, EnvironmentFolderOrRootOfConfigurations) {
  ModelSearch s;
  s.env_dir = tmp / "env";
  make_models(tmp / "env");
  EXPECT_EQ(find_models(s), tmp / "env");
  s.env_dir = tmp / "root";
  make_models(tmp / "root" / "compact");
  make_models(tmp / "root" / "paper");
  EXPECT_EQ(find_models(s), tmp / "root" / "compact") << "no DEFAULT: compact";
  write_file(tmp / "root" / "DEFAULT", "paper\n");
  EXPECT_EQ(find_models(s), tmp / "root" / "paper");
  s.config = "compact";
  EXPECT_EQ(find_models(s), tmp / "root" / "compact");
  s.config = "missing";
  EXPECT_THROW(find_models(s), raindrop::Error) << "$RAINDROP_MODELS is authoritative";
  s.config = "../escape";
  EXPECT_THROW(find_models(s), raindrop::Error);
}

TEST_F(ModelSearchTest, InstalledLocationBeforeSourceTree) {
  ModelSearch s;
  s.executable = tmp / "prefix" / "bin" / "raindrop-remove";
  s.source_models = tmp / "src" / "models";
  make_models(tmp / "src" / "models" / "compact");
  EXPECT_EQ(find_models(s), tmp / "src" / "models" / "compact");
  make_models(tmp / "prefix" / "share" / "raindrop" / "models" / "compact");
  EXPECT_EQ(find_models(s), tmp / "prefix" / "share" / "raindrop" / "models" / "compact");
  s.config = "paper";
  try {
    find_models(s);
    FAIL() << "expected an error";
  } catch (const raindrop::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("share/raindrop/models/paper"), std::string::npos) << msg;
    EXPECT_NE(msg.find("src/models/paper"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--models"), std::string::npos) << msg;
  }
}

// DEFAULT's "vnni NAME" line: its int8 copy where int8 runs fast, the first line elsewhere, and
// never over a configuration asked for by name or a copy that holds no models.
TEST_F(ModelSearchTest, DefaultsInt8CopyOnlyWhereInt8RunsFast) {
  ModelSearch s;
  s.env_dir = tmp / "root";
  make_models(tmp / "root" / "main");
  write_file(tmp / "root" / "DEFAULT", "main\r\n# the int8 copy\n\nvnni main-int8  # a note\r\n");
  std::string why = "stale";
  s.int8_fast = true;
  EXPECT_EQ(find_models(s, &why), tmp / "root" / "main") << "the copy holds no models yet";
  EXPECT_EQ(why, "");
  make_models(tmp / "root" / "main-int8");
  EXPECT_EQ(find_models(s, &why), tmp / "root" / "main-int8");
  EXPECT_NE(why.find("int8 copy of main"), std::string::npos) << why;
  s.int8_fast = false;
  EXPECT_EQ(find_models(s, &why), tmp / "root" / "main");
  EXPECT_EQ(why, "");
  s.int8_fast = true;
  s.config = "main";
  EXPECT_EQ(find_models(s), tmp / "root" / "main") << "--model-config names the float one";
  // The installed location and the source tree read it the same way.
  ModelSearch t;
  t.source_models = tmp / "root";
  t.int8_fast = true;
  EXPECT_EQ(find_models(t), tmp / "root" / "main-int8");
  EXPECT_EQ(read_default_config(tmp / "root", true), "main-int8");
  EXPECT_EQ(read_default_config(tmp / "root", false), "main");
  for (const char* bad : {"main\nvnni\n", "main\nvnni a b\n", "main\navx2 main-int8\n", "main\nvnni ../x\n",
                          "main\nvnni main-int8\nvnni main\n"}) {
    write_file(tmp / "root" / "DEFAULT", bad);
    EXPECT_THROW(find_models(t), raindrop::Error) << bad;
  }
}

TEST_F(ModelSearchTest, LargeDropModelsAreTheSiblingThatLargeDropsNames) {
  make_models(tmp / "root" / "compact");
  EXPECT_FALSE(large_drop_companion(tmp / "root" / "compact").has_value()) << "no LARGE_DROPS file: none";
  write_file(tmp / "root" / "compact" / "LARGE_DROPS", "  coarse \n");
  const fs::path expected = fs::weakly_canonical(tmp / "root") / "coarse";
  EXPECT_EQ(large_drop_companion(tmp / "root" / "compact"), expected);
  EXPECT_EQ(large_drop_companion(tmp / "root" / "compact" / ""), expected) << "a trailing slash names the same folder";
  EXPECT_EQ(large_drop_companion(tmp / "root" / "." / "compact"), expected);
  write_file(tmp / "root" / "compact" / "LARGE_DROPS", "../../escape\n");
  EXPECT_THROW(large_drop_companion(tmp / "root" / "compact"), raindrop::Error);
}

TEST_F(ModelSearchTest, ModelFilesAreCheckedByName) {
  make_models(tmp / "full");
  EXPECT_NO_THROW(check_model_files(tmp / "full"));
  fs::remove(tmp / "full" / "rfn.onnx");
  try {
    check_model_files(tmp / "full");
    FAIL() << "expected an error";
  } catch (const raindrop::Error& e) {
    EXPECT_NE(std::string(e.what()).find("rfn.onnx"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(same_folder(tmp / "full", tmp / "." / "full" / ""));
  EXPECT_FALSE(same_folder(tmp / "full", tmp / "other"));
}

// compact-multiscale: compact's detector with 3RN and RFN fine-tuned for frames larger than the working size
// (docs/RESULTS.md 3.4); compact stays committed beside it.
// Its int8 copy (quantized from it, the same scores within a few hundredths of a dB: docs/RESULTS.md
// 4.49, 4.60) on CPUs with VNNI; this process's own search says which it takes here.
TEST(ModelDefault, SourceTreeNamesCompactMultiscale) {
  EXPECT_EQ(read_default_config(source_dir() / "models").value_or("<none>"), "compact-multiscale");
  EXPECT_EQ(read_default_config(source_dir() / "models", true).value_or("<none>"), "compact-multiscale-int8");
  EXPECT_NO_THROW(check_model_files(source_dir() / "models" / "compact-multiscale-int8"));
  ModelSearch s;
  s.source_models = source_dir() / "models";
  s.int8_fast = default_model_search().int8_fast;
  EXPECT_EQ(s.int8_fast, raindrop::removal::int8_runs_fast());
  EXPECT_EQ(find_models(s).filename(), s.int8_fast ? "compact-multiscale-int8" : "compact-multiscale");
  EXPECT_NO_THROW(check_model_files(source_dir() / "models" / "compact-multiscale"));
  EXPECT_NO_THROW(check_model_files(source_dir() / "models" / "compact"));
}

// The default's large drops go to a committed sibling that holds all three graphs (compact
// has its own LARGE_DROPS too, so that --model-config compact also runs the coarse pass's models).
TEST(ModelDefault, TheDefaultsLargeDropModelsAreCommitted) {
  for (const char* config : {"compact-multiscale", "compact"}) {
    const auto large = large_drop_companion(source_dir() / "models" / config);
    ASSERT_TRUE(large.has_value()) << "models/" << config << "/LARGE_DROPS is missing";
    EXPECT_NO_THROW(check_model_files(*large));
    EXPECT_FALSE(same_folder(*large, source_dir() / "models" / config));
  }
}

}  // namespace
}  // namespace removetest
