// End-to-end: --shard K/N. The N shards of a run, one after another or side by side in one
// folder, and their parts merged, are byte for byte the folder of one run; a shard resumes
// on its own; the locks let shards share a folder but nothing else; bad K/N are refused.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "cli_test_util.h"

namespace clitest {
namespace {

constexpr int kImages = 8, kShards = 3;

// The names of the files that differ between two folder snapshots (empty: identical), so
// that a failure does not print the images.
std::vector<std::string> differences(const std::map<std::string, std::string>& a,
                                     const std::map<std::string, std::string>& b) {
  std::set<std::string> names;
  for (const auto& [n, bytes] : a) names.insert(n);
  for (const auto& [n, bytes] : b) names.insert(n);
  std::vector<std::string> differ;
  for (const auto& n : names) {
    if (!a.count(n) || !b.count(n) || a.at(n) != b.at(n)) differ.push_back(n);
  }
  return differ;
}

class RenderShards : public ::testing::Test {
 protected:
  void SetUp() override {
    for (int i = 0; i < kImages; ++i)
      write_image(tmp / "in" / ("frame_" + std::to_string(i) + ".png"), make_background(320, 160, i));
  }

  static std::vector<std::string> args(const std::string& out, const std::string& shard = "") {
    std::vector<std::string> a{"-i", "in", "--out", out, "--variants", "2", "--seed", "7", "-j", "1", "-q"};
    if (!shard.empty()) a.insert(a.end(), {"--shard", shard});
    return a;
  }
  static std::string shard(int k) { return std::to_string(k) + "/" + std::to_string(kShards); }

  RunResult render(const std::vector<std::string>& a) { return run_render(a, tmp.path()); }

  // The folder of one run without --shard.
  std::map<std::string, std::string> one_run() {
    const RunResult r = render(args("one"));
    EXPECT_EQ(r.code, 0) << r.describe();
    return snapshot(tmp / "one");
  }

  void merge(const std::string& out) {
    const RunResult r = render({"--merge-shards", out});
    ASSERT_EQ(r.code, 0) << r.describe();
    EXPECT_NE(r.err.find(std::to_string(kImages * 2) + " samples"), std::string::npos) << r.describe();
  }

  TempDir tmp;
};

TEST_F(RenderShards, ShardsOneAfterAnotherMakeOneRun) {
  const auto expected = one_run();
  std::set<std::string> ids;
  std::map<std::string, int> shard_of_input;  // both variants of an input in one shard
  long rendered = 0;
  for (int k = 0; k < kShards; ++k) {
    const RunResult r = render(args("sharded", shard(k)));
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto counts = parse_counts(r.err);
    ASSERT_TRUE(counts) << r.describe();
    rendered += counts->rendered;
    // Each shard's part lists its own samples only, sorted by id.
    const auto lines = split_lines(read_file(tmp / "sharded" / ("manifest.part-" + std::to_string(k) + "-of-3.jsonl")));
    EXPECT_EQ(static_cast<long>(lines.size()), counts->rendered);
    EXPECT_TRUE(std::is_sorted(lines.begin(), lines.end()));
    for (const auto& l : lines) {
      const std::string id = json::parse(l)["id"];
      EXPECT_TRUE(ids.insert(id).second) << l;
      const auto [it, fresh] = shard_of_input.emplace(id.substr(0, id.rfind("_v")), k);
      EXPECT_TRUE(fresh || it->second == k) << id << " apart from its other variant";
    }
  }
  EXPECT_EQ(rendered, kImages * 2) << "every sample rendered by exactly one shard";
  EXPECT_FALSE(fs::exists(tmp / "sharded" / "manifest.jsonl")) << "no manifest.jsonl before the merge";
  merge("sharded");
  EXPECT_EQ(differences(snapshot(tmp / "sharded"), expected), std::vector<std::string>{}) << "the merged shards are not the one run";
}

TEST_F(RenderShards, ShardsSideBySideInOneFolder) {
  const auto expected = one_run();
  // Shards 0 and 1 at the same time into one folder, then shard 2.
  const auto together = testsupport::run_captured_together(render_bin(), {args("shared", shard(0)), args("shared", shard(1))},
                                                           tmp.path());
  for (const auto& r : together) ASSERT_EQ(r.code, 0) << r.describe();
  const RunResult last = render(args("shared", shard(2)));
  ASSERT_EQ(last.code, 0) << last.describe();
  merge("shared");
  EXPECT_EQ(differences(snapshot(tmp / "shared"), expected), std::vector<std::string>{});
}

TEST_F(RenderShards, AWholeRunAfterSomeShardsRendersTheRestAndMerges) {
  const auto expected = one_run();
  ASSERT_EQ(render(args("mixed", shard(0))).code, 0);
  ASSERT_EQ(render(args("mixed", shard(2))).code, 0);
  const RunResult r = render(args("mixed"));
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto counts = parse_counts(r.err);
  ASSERT_TRUE(counts) << r.describe();
  EXPECT_GT(counts->skipped, 0) << r.describe();
  EXPECT_EQ(counts->rendered + counts->skipped, kImages * 2) << r.describe();
  EXPECT_EQ(differences(snapshot(tmp / "mixed"), expected), std::vector<std::string>{}) << "the parts are merged and removed";
}

TEST_F(RenderShards, OneShardResumes) {
  const auto expected = one_run();
  for (int k = 0; k < kShards; ++k) ASSERT_EQ(render(args("resumed", shard(k))).code, 0);
  // Shard 1 as if killed: one sample's images gone, a partly appended line, a temporary.
  const fs::path part = tmp / "resumed" / "manifest.part-1-of-3.jsonl";
  const auto lines = split_lines(read_file(part));
  ASSERT_GE(lines.size(), 2u);
  const std::string lost = json::parse(lines[0])["id"];
  fs::remove(tmp / "resumed" / "rainy" / (lost + ".png"));
  write_file(part, read_file(part) + lines[1].substr(0, lines[1].size() / 2));
  write_file(tmp / "resumed" / "clean" / ("." + lost + ".png.tmp-999999999-0"), "partial");
  // A temporary of another shard's sample, being written right now: not touched.
  const std::string other = json::parse(split_lines(read_file(tmp / "resumed" / "manifest.part-0-of-3.jsonl"))[0])["id"];
  const fs::path others_tmp = tmp / "resumed" / "clean" / ("." + other + ".png.tmp-999999999-1");
  write_file(others_tmp, "in flight");

  const RunResult r = render(args("resumed", shard(1)));
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto counts = parse_counts(r.err);
  ASSERT_TRUE(counts) << r.describe();
  EXPECT_EQ(counts->rendered, 1) << r.describe();
  EXPECT_EQ(counts->skipped, static_cast<long>(lines.size()) - 1) << r.describe();
  EXPECT_TRUE(fs::exists(others_tmp)) << "a shard removed another shard's temporary";
  fs::remove(others_tmp);
  merge("resumed");
  EXPECT_EQ(differences(snapshot(tmp / "resumed"), expected), std::vector<std::string>{});
}

TEST_F(RenderShards, AShardRerunAfterTheMergeFindsItsSamplesDone) {
  const auto expected = one_run();
  for (int k = 0; k < kShards; ++k) ASSERT_EQ(render(args("merged", shard(k))).code, 0);
  merge("merged");
  const RunResult r = render(args("merged", shard(1)));
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto counts = parse_counts(r.err);
  ASSERT_TRUE(counts) << r.describe();
  EXPECT_EQ(counts->rendered, 0) << r.describe();
  EXPECT_GT(counts->skipped, 0) << r.describe();
  merge("merged");
  EXPECT_EQ(differences(snapshot(tmp / "merged"), expected), std::vector<std::string>{});
}

// A shard at work holds the folder's lock shared and its own shard's exclusively: played
// here by the test process itself.
TEST_F(RenderShards, LocksLetShardsShareTheFolderOnly) {
  fs::create_directories(tmp / "busy");
  const int folder = ::open((tmp / "busy" / ".raindrop-render.lock").c_str(), O_RDWR | O_CREAT, 0644);
  const int own = ::open((tmp / "busy" / ".raindrop-render.shard-1-of-3.lock").c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_TRUE(folder >= 0 && own >= 0);
  ASSERT_EQ(::flock(folder, LOCK_SH | LOCK_NB), 0);
  ASSERT_EQ(::flock(own, LOCK_EX | LOCK_NB), 0);
  const RunResult same = render(args("busy", shard(1)));
  EXPECT_EQ(same.code, 1) << same.describe();
  EXPECT_NE(same.err.find("shard 1/3 of output folder 'busy' is in use"), std::string::npos) << same.describe();
  const RunResult whole = render(args("busy"));
  EXPECT_EQ(whole.code, 1) << whole.describe();
  EXPECT_NE(whole.err.find("output folder 'busy' is in use"), std::string::npos) << whole.describe();
  const RunResult merging = render({"--merge-shards", "busy"});
  EXPECT_EQ(merging.code, 1) << merging.describe();
  EXPECT_NE(merging.err.find("in use"), std::string::npos) << merging.describe();
  const RunResult other = render(args("busy", shard(0)));
  EXPECT_EQ(other.code, 0) << "another shard runs beside it\n" << other.describe();
  EXPECT_TRUE(fs::exists(tmp / "busy" / ".raindrop-render.lock")) << "removed while still held";
  ::close(own);
  ::close(folder);
}

TEST_F(RenderShards, BadShardsAreRefused) {
  for (const char* bad : {"3/3", "4/3", "-1/3", "0/0", "1/-2", "1", "a/b", "1/3x", "/3", "1/", "99999999999/3"}) {
    const RunResult r = render(args("bad", bad));
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.describe();
    const auto lines = r.message_lines();
    ASSERT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_NE(lines[0].find("--shard"), std::string::npos) << r.describe();
  }
  EXPECT_FALSE(fs::exists(tmp / "bad"));
  EXPECT_EQ(render({"--merge-shards", "bad", "-i", "in"}).code, 2) << "merge takes no inputs";
  // 0/1 is the whole run.
  const auto expected = one_run();
  EXPECT_EQ(render(args("whole", "0/1")).code, 0);
  EXPECT_EQ(differences(snapshot(tmp / "whole"), expected), std::vector<std::string>{});
}

TEST_F(RenderShards, MergeRefusesAnIncompleteOrMixedFolder) {
  ASSERT_EQ(render(args("part", shard(0))).code, 0);
  ASSERT_EQ(render(args("part", shard(2))).code, 0);
  const RunResult missing = render({"--merge-shards", "part"});
  EXPECT_EQ(missing.code, 1) << missing.describe();
  EXPECT_NE(missing.err.find("shard 1/3 has not run"), std::string::npos) << missing.describe();
  // A shard split another way is refused before it renders anything (the merge would refuse it
  // after every shard had run).
  const RunResult other_n = render(args("part", "0/2"));
  EXPECT_EQ(other_n.code, 1) << other_n.describe();
  EXPECT_EQ(split_lines(other_n.err).size(), 1u) << other_n.describe();
  EXPECT_NE(other_n.err.find("split 3 ways, and --shard 0/2 splits it 2 ways"), std::string::npos) << other_n.describe();
  EXPECT_FALSE(fs::exists(tmp / "part" / "manifest.part-0-of-2.jsonl"));
  // The merge's own check, for parts that came together some other way (copied in).
  fs::copy_file(tmp / "part" / "manifest.part-0-of-3.jsonl", tmp / "part" / "manifest.part-0-of-2.jsonl");
  const RunResult mixed = render({"--merge-shards", "part"});
  EXPECT_EQ(mixed.code, 1) << mixed.describe();
  EXPECT_NE(mixed.err.find("split 2 and 3 ways"), std::string::npos) << mixed.describe();
  EXPECT_FALSE(fs::exists(tmp / "part" / "manifest.jsonl"));
  const RunResult none = render({"--merge-shards", "in"});
  EXPECT_EQ(none.code, 1) << none.describe();
}

}  // namespace
}  // namespace clitest
