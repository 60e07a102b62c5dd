// raindrop-remove --shard K/N in folder mode: the N shards, one after another or side by
// side into one folder, write exactly the files of one run; bad K/N and a single image are
// usage errors.
#include "remove_test_util.h"

namespace removetest {
namespace {

constexpr int kShards = 3;

class RemoveShards : public ::testing::Test {
 protected:
  void SetUp() override {
    for (int i = 0; i < 9; ++i)
      write_image(tmp / "in" / (i % 3 == 0 ? "sub" : ".") / ("img_" + std::to_string(i) + ".png"),
                  make_image(48 + 8 * i, 40, i));
  }
  static std::vector<std::string> args(const std::string& out, const std::string& shard = "") {
    std::vector<std::string> a{"in", out, "--mask-dir", out + "-masks", "-j", "1", "-q",
                               "--models", smoke_models().string()};
    if (!shard.empty()) a.insert(a.end(), {"--shard", shard});
    return a;
  }
  static std::string shard(int k) { return std::to_string(k) + "/" + std::to_string(kShards); }

  // Every file under out/ and out-masks/: relative path -> bytes.
  std::map<std::string, std::string> files(const std::string& out) {
    std::map<std::string, std::string> all;
    for (const std::string& dir : {out, out + "-masks"}) {
      if (!fs::exists(tmp / dir)) continue;
      for (const auto& e : fs::recursive_directory_iterator(tmp / dir)) {
        if (e.is_regular_file())
          all[dir.substr(out.size()) + "/" + fs::relative(e.path(), tmp / dir).generic_string()] = read_file(e.path());
      }
    }
    return all;
  }

  TempDir tmp;
};

TEST_F(RemoveShards, ShardsMakeOneRun) {
  const RunResult one = run_remove(args("one"), tmp.path());
  ASSERT_EQ(one.code, 0) << one.describe();
  const auto expected = files("one");
  ASSERT_EQ(expected.size(), 18u);

  for (int k = 0; k < kShards; ++k) {
    const RunResult r = run_remove(args("seq", shard(k)), tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
  }
  EXPECT_TRUE(files("seq") == expected) << "the shards wrote other files than one run";

  // Two shards side by side, then the third.
  const auto together = testsupport::run_captured_together(
      remove_bin(), {args("par", shard(0)), args("par", shard(1))}, tmp.path(), "env -u RAINDROP_MODELS ");
  for (const auto& r : together) ASSERT_EQ(r.code, 0) << r.describe();
  ASSERT_EQ(run_remove(args("par", shard(2)), tmp.path()).code, 0);
  EXPECT_TRUE(files("par") == expected) << "the shards side by side wrote other files than one run";
  EXPECT_TRUE(hidden_temporaries(tmp.path()).empty());
}

TEST_F(RemoveShards, EachShardTakesItsOwnImages) {
  std::map<std::string, int> owner;
  for (int k = 0; k < kShards; ++k) {
    const std::string out = "s" + std::to_string(k);
    const RunResult r = run_remove(args(out, shard(k)), tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    for (const auto& [rel, bytes] : files(out)) {
      if (rel.rfind("-masks", 0) == 0) continue;
      EXPECT_TRUE(owner.emplace(rel, k).second) << rel << " written by shards " << owner[rel] << " and " << k;
    }
  }
  EXPECT_EQ(owner.size(), 9u);
}

TEST_F(RemoveShards, BadShardsAreUsageErrors) {
  for (const char* bad : {"3/3", "-1/3", "0/0", "x", "1/3/4"}) {
    const RunResult r = run_remove(args("bad", bad), tmp.path());
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.describe();
    EXPECT_NE(r.err.find("--shard"), std::string::npos) << r.describe();
  }
  const RunResult file = run_remove({"in/img_1.png", "x.png", "--shard", "0/2", "--models", smoke_models().string()},
                                    tmp.path());
  EXPECT_EQ(file.code, 2) << file.describe();
  EXPECT_EQ(split_lines(file.err).size(), 1u) << file.describe();
  EXPECT_NE(file.err.find("--shard"), std::string::npos) << file.describe();
  EXPECT_FALSE(fs::exists(tmp / "bad"));
  EXPECT_FALSE(fs::exists(tmp / "x.png"));
}

}  // namespace
}  // namespace removetest
