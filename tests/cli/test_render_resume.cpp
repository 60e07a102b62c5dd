// End-to-end: a run killed with SIGKILL leaves only complete images under final names and
// resumes to exactly the bytes of an uninterrupted run; a folder rendered with other settings
// is refused without touching it.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "cli_test_util.h"

namespace clitest {
namespace {

constexpr int kImages = 12, kVariants = 2;

// 12 generated 1024x512 inputs in <root>/in: enough work (~1-3 s with -j 1) to be killed
// part-way.
void make_inputs(const fs::path& root) {
  for (int i = 0; i < kImages; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%02d.png", i);
    write_image(root / "in" / name, make_background(1024, 512, i));
  }
}

std::vector<std::string> render_args(const std::string& out) {
  return {"-i", "in", "--out", out, "--variants", std::to_string(kVariants), "--seed", "3", "-j", "1", "-q"};
}

// raindrop-render started in the background (fork + exec), output to files in `cwd`/_logs.
class Background {
 public:
  Background(const std::vector<std::string>& args, const fs::path& cwd) {
    fs::create_directories(cwd / "_logs");
    const std::string err = (cwd / "_logs" / "background-stderr").string();
    std::vector<std::string> argv_s = {render_bin().string()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      if (::chdir(cwd.c_str()) != 0) ::_exit(126);
      const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int devnull = ::open("/dev/null", O_RDWR);
      if (fd < 0 || devnull < 0) ::_exit(126);
      ::dup2(devnull, 0);
      ::dup2(devnull, 1);
      ::dup2(fd, 2);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  ~Background() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool valid() const { return pid_ > 0; }
  bool running() {
    if (reaped_) return false;
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      reaped_ = true;
      status_ = status;
      return false;
    }
    return true;
  }
  // SIGKILL, then reap; returns the wait status.
  int kill_now() {
    if (!reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status_, 0);
      reaped_ = true;
    }
    return status_;
  }

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
  int status_ = 0;
};

// Starts `args`, waits until <out>/manifest.jsonl has at least `lines` newline-terminated
// lines, then kills the process with SIGKILL while it is still rendering.
void render_and_kill(const std::vector<std::string>& args, const fs::path& cwd, const fs::path& manifest,
                     size_t lines) {
  Background bg(args, cwd);
  ASSERT_TRUE(bg.valid()) << "fork failed";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (count_newlines(manifest) < lines) {
    ASSERT_TRUE(bg.running()) << "the render finished (or died) before " << lines
                              << " manifest lines appeared; stderr:\n"
                              << read_file(cwd / "_logs" / "background-stderr");
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "no progress within 120 s";
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(bg.running()) << "the render finished before it could be killed";
  const int status = bg.kill_now();
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "wait status " << status;
}

void expect_same_files(const fs::path& got_dir, const fs::path& want_dir) {
  const auto got = snapshot(got_dir), want = snapshot(want_dir);
  EXPECT_EQ(list_files(got_dir), list_files(want_dir));
  for (const auto& [name, bytes] : want) {
    const auto it = got.find(name);
    if (it == got.end()) continue;  // reported by the listing comparison
    EXPECT_TRUE(it->second == bytes) << name << " differs from the uninterrupted run";
  }
}

TEST(RenderResume, KilledRunResumesToIdenticalBytes) {
  TempDir tmp;
  make_inputs(tmp.path());
  const size_t total = kImages * kVariants;

  // Reference: one uninterrupted run.
  const auto ref = run_render(render_args("reference"), tmp.path());
  ASSERT_EQ(ref.code, 0) << ref.describe();
  ASSERT_EQ(manifest_lines(tmp / "reference").size(), total);

  // Killed part-way.
  render_and_kill(render_args("out"), tmp.path(), tmp / "out" / "manifest.jsonl", 2);
  if (HasFatalFailure()) return;
  const size_t lines_at_kill = count_newlines(tmp / "out" / "manifest.jsonl");
  ASSERT_LT(lines_at_kill, total) << "the run was not interrupted";

  // Whatever carries a final name must be a complete image.
  const auto left = sample_files(tmp / "out");
  size_t final_named = 0;
  for (const auto& rel : left) {
    const std::string name = fs::path(rel).filename().string();
    if (name[0] == '.') continue;  // a hidden temporary: allowed after a kill
    ++final_named;
    std::string why;
    const auto img = read_image(tmp / "out" / rel, &why);
    EXPECT_TRUE(img) << rel << " is not a complete image after the kill: " << why;
    if (img) {
      EXPECT_EQ(img->width, 1024) << rel;
      EXPECT_EQ(img->height, 512) << rel;
    }
  }
  EXPECT_GE(final_named, 3 * 2u) << "the manifest had 2 lines, so at least 2 samples' images exist";

  // Rerun: skips the finished samples, renders the rest.
  const auto again = run_render(render_args("out"), tmp.path());
  ASSERT_EQ(again.code, 0) << again.describe();
  const auto counts = parse_counts(again.err);
  ASSERT_TRUE(counts) << again.describe();
  EXPECT_GT(counts->skipped, 0) << again.describe();
  EXPECT_GE(counts->skipped, 2) << "the manifest held 2 finished samples";
  EXPECT_EQ(counts->rendered + counts->skipped, static_cast<long>(total)) << again.describe();
  EXPECT_EQ(counts->failed, 0);
  EXPECT_TRUE(hidden_temporaries(tmp / "out").empty())
      << ::testing::PrintToString(hidden_temporaries(tmp / "out"));

  expect_same_files(tmp / "out", tmp / "reference");

  // A third run has nothing left to do and changes nothing.
  const auto before = snapshot(tmp / "out");
  const auto third = run_render(render_args("out"), tmp.path());
  ASSERT_EQ(third.code, 0) << third.describe();
  const auto c3 = parse_counts(third.err);
  ASSERT_TRUE(c3) << third.describe();
  EXPECT_EQ(c3->rendered, 0);
  EXPECT_EQ(c3->skipped, static_cast<long>(total));
  EXPECT_TRUE(snapshot(tmp / "out") == before) << "a run with nothing to do changed the folder";
}

// manifest.h: "A run that is killed leaves at worst a truncated last line, which the next run
// ignores". A manifest line is several kB (one record per drop), longer than the stream
// buffer, so a SIGKILL can land between two write() calls of one line. The next run appends
// after that partial line; if it is killed too, the partial line is no longer the last one.
// A third run must still resume.
TEST(RenderResume, SurvivesTwoKillsAfterATruncatedManifestLine) {
  TempDir tmp;
  make_inputs(tmp.path());
  const size_t total = kImages * kVariants;
  const auto ref = run_render(render_args("reference"), tmp.path());
  ASSERT_EQ(ref.code, 0) << ref.describe();
  const auto ref_lines = manifest_lines(tmp / "reference");
  ASSERT_EQ(ref_lines.size(), total);
  ASSERT_GT(ref_lines[4].size(), 200u);

  // The state a kill in the middle of appending line 5 leaves: 4 whole lines, half a line.
  fs::copy(tmp / "reference", tmp / "out", fs::copy_options::recursive);
  std::string manifest;
  for (int i = 0; i < 4; ++i) manifest += ref_lines[i] + "\n";
  manifest += ref_lines[4].substr(0, ref_lines[4].size() / 2);
  write_file(tmp / "out" / "manifest.jsonl", manifest);

  // Second run, killed once it has appended a few lines.
  render_and_kill(render_args("out"), tmp.path(), tmp / "out" / "manifest.jsonl", 7);
  if (HasFatalFailure()) return;

  // Third run.
  const auto third = run_render(render_args("out"), tmp.path());
  ASSERT_EQ(third.code, 0) << "resuming after two kills failed\n" << third.describe();
  EXPECT_TRUE(hidden_temporaries(tmp / "out").empty());
  expect_same_files(tmp / "out", tmp / "reference");
}

// Two small generated inputs in <tmp>/in, rendered once with `args` (2 variants, into out/).
void render_two_inputs(const TempDir& tmp, const std::vector<std::string>& args) {
  write_image(tmp / "in" / "one.png", make_background(320, 160, 0));
  write_image(tmp / "in" / "two.png", make_background(256, 200, 1));
  const auto first = run_render(args, tmp.path());
  ASSERT_EQ(first.code, 0) << first.describe();
  ASSERT_EQ(manifest_lines(tmp / "out").size(), 4u);
}

// Resume skips a sample only when the manifest lists it AND its files exist: a finished
// sample that lost one image (deleted by hand, or a disk cleaned up) is rendered again, to
// the same bytes, and the samples that are whole are left alone.
TEST(RenderResume, ASampleMissingAnImageIsRenderedAgain) {
  TempDir tmp;
  const std::vector<std::string> args = {"-i", "in", "--out", "out", "--variants", "2", "--seed", "6", "-j", "2", "-q"};
  render_two_inputs(tmp, args);
  if (HasFatalFailure()) return;
  const auto before = snapshot(tmp / "out");
  for (const char* lost : {"rainy/two_v01.png", "mask/one_v00.png", "clean/two_v00.png"}) {
    SCOPED_TRACE(lost);
    ASSERT_TRUE(fs::remove(tmp / "out" / lost)) << "the first run did not write " << lost;
    const auto again = run_render(args, tmp.path());
    ASSERT_EQ(again.code, 0) << again.describe();
    const auto counts = parse_counts(again.err);
    ASSERT_TRUE(counts) << again.describe();
    EXPECT_EQ(counts->rendered, 1) << again.describe();
    EXPECT_EQ(counts->skipped, 3) << again.describe();
    ASSERT_TRUE(fs::exists(tmp / "out" / lost)) << "not rendered again";
    // Every image is the first run's, byte for byte (the manifest gains a line).
    const auto after = snapshot(tmp / "out");
    for (const auto& [name, bytes] : before) {
      if (name == "manifest.jsonl") continue;
      const auto it = after.find(name);
      ASSERT_NE(it, after.end()) << name;
      EXPECT_TRUE(it->second == bytes) << name << " differs from the first run";
    }
  }
}

TEST(RenderResume, RefusesFolderRenderedWithOtherSettings) {
  TempDir tmp;
  const std::vector<std::string> base = {"-i", "in", "--out", "out", "--variants", "2", "--seed", "4", "-j", "2", "-q"};
  render_two_inputs(tmp, base);
  if (HasFatalFailure()) return;
  const auto before = snapshot(tmp / "out");

  const std::vector<std::vector<std::string>> changes = {
      {"--seed", "5"}, {"--scene", "full-physics"}, {"--size", "128x64"}, {"--convert"}};
  for (const auto& change : changes) {
    SCOPED_TRACE("rerun with " + ::testing::PrintToString(change));
    auto args = base;
    // Replace the seed in place rather than passing --seed twice.
    if (change[0] == "--seed") {
      args[7] = change[1];
    } else {
      args.insert(args.end(), change.begin(), change.end());
    }
    const auto r = run_render(args, tmp.path());
    EXPECT_EQ(r.code, 1) << r.describe();
    const auto lines = r.message_lines();
    ASSERT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_EQ(lines[0].rfind("raindrop-render: error: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find("other settings"), std::string::npos) << lines[0];
    EXPECT_TRUE(snapshot(tmp / "out") == before) << "the refused run changed the folder: "
                                                 << ::testing::PrintToString(list_files(tmp / "out"));
  }
  // The same settings are still accepted.
  const auto same = run_render(base, tmp.path());
  EXPECT_EQ(same.code, 0) << same.describe();
  const auto counts = parse_counts(same.err);
  ASSERT_TRUE(counts) << same.describe();
  EXPECT_EQ(counts->skipped, 4);
  EXPECT_EQ(counts->rendered, 0);
  EXPECT_TRUE(snapshot(tmp / "out") == before);
}



// A sample is resumed only from the image it was rendered from: the same file name in another
// input folder (in/one.png, then other/one.png) is refused, not counted as done under a
// manifest that names the first image. The same folder given another way is still itself.
TEST(RenderResume, RefusesASampleOfAnotherImageWithTheSameName) {
  TempDir tmp;
  const std::vector<std::string> base = {"-i", "in", "--out", "out", "--variants", "2", "--seed", "4", "-j", "2", "-q"};
  render_two_inputs(tmp, base);
  if (HasFatalFailure()) return;
  const auto before = snapshot(tmp / "out");
  write_image(tmp / "other" / "one.png", make_background(320, 160, 7));
  auto args = base;
  args[1] = "other";
  const auto r = run_render(args, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  const auto lines = r.message_lines();
  ASSERT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_NE(lines[0].find("rendered from 'in/one.png'"), std::string::npos) << lines[0];
  EXPECT_TRUE(snapshot(tmp / "out") == before);
  args[1] = "./in/";
  const auto same = run_render(args, tmp.path());
  ASSERT_EQ(same.code, 0) << same.describe();
  const auto counts = parse_counts(same.err);
  ASSERT_TRUE(counts) << same.describe();
  EXPECT_EQ(counts->skipped, 4);
}

// A folder holding the user's own files: a manifest.jsonl of one whole line that is no record
// is not an interrupted append (that leaves a line cut short, without its line break), and a
// hidden file that only looks like a temporary is not one of ours. Both used to be replaced
// or deleted; now the run is refused and they are kept.
TEST(RenderResume, KeepsAUsersManifestAndHiddenFiles) {
  TempDir tmp;
  write_image(tmp / "in" / "one.png", make_background(320, 160, 0));
  write_file(tmp / "out" / "manifest.jsonl", "{\"my\": \"own notes\"}\n");
  write_file(tmp / "out" / ".notes.tmp-keep", "mine");
  write_file(tmp / "keep" / ".notes.tmp-keep", "mine");
  const auto r = run_render({"-i", "in", "--out", "out", "-q"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("is not a manifest record"), std::string::npos) << r.describe();
  EXPECT_EQ(read_file(tmp / "out" / "manifest.jsonl"), "{\"my\": \"own notes\"}\n");
  EXPECT_TRUE(fs::exists(tmp / "out" / ".notes.tmp-keep"));
  // A run into a folder without a manifest cleans up only its own kind of temporaries.
  write_file(tmp / "keep" / ".one_v00.png.tmp-12345-0", "stale");
  const auto k = run_render({"-i", "in", "--out", "keep", "-q"}, tmp.path());
  ASSERT_EQ(k.code, 0) << k.describe();
  EXPECT_EQ(read_file(tmp / "keep" / ".notes.tmp-keep"), "mine");
  EXPECT_FALSE(fs::exists(tmp / "keep" / ".one_v00.png.tmp-12345-0"));
}

// A file of the data set made read-only (chmod a-w: a sample kept as it is, a manifest frozen)
// is not written over by a resumed run, whoever runs it: the run stops with one line, before
// writing anything. (Files are replaced by a rename, which needs only the folder's permission.)
TEST(RenderResume, KeepsReadOnlyFiles) {
  TempDir tmp;
  write_image(tmp / "in" / "one.png", make_background(320, 160, 0));
  const std::vector<std::string> args = {"-i", "in", "--out", "out", "--variants", "2", "-q"};
  ASSERT_EQ(run_render(args, tmp.path()).code, 0);
  // one_v00 incomplete (its rainy image gone), its clean image read-only.
  fs::remove(tmp / "out" / "rainy" / "one_v00.png");
  const fs::path clean = tmp / "out" / "clean" / "one_v00.png";
  const std::string before = read_file(clean);
  fs::permissions(clean, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  const std::string manifest = read_file(tmp / "out" / "manifest.jsonl");
  const auto r = run_render(args, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  ASSERT_EQ(r.message_lines().size(), 1u) << r.describe();
  EXPECT_NE(r.err.find("read-only"), std::string::npos) << r.describe();
  EXPECT_EQ(read_file(clean), before);
  EXPECT_FALSE(fs::exists(tmp / "out" / "rainy" / "one_v00.png"));
  EXPECT_EQ(read_file(tmp / "out" / "manifest.jsonl"), manifest);
  // The manifest itself read-only: the same.
  fs::permissions(clean, fs::perms::owner_write, fs::perm_options::add);
  fs::permissions(tmp / "out" / "manifest.jsonl", fs::perms::owner_read);
  const auto m = run_render(args, tmp.path());
  EXPECT_EQ(m.code, 1) << m.describe();
  EXPECT_NE(m.err.find("manifest.jsonl': read-only"), std::string::npos) << m.describe();
  EXPECT_FALSE(fs::exists(tmp / "out" / "rainy" / "one_v00.png"));
  // Writable again: the sample is completed.
  fs::permissions(tmp / "out" / "manifest.jsonl", fs::perms::owner_write, fs::perm_options::add);
  ASSERT_EQ(run_render(args, tmp.path()).code, 0);
  EXPECT_TRUE(fs::exists(tmp / "out" / "rainy" / "one_v00.png"));
}

// Two runs into one folder: the second used to delete the first's temporaries (which then
// died with "cannot move the finished file into place"). The folder is locked for a run: a
// second run is refused with one line naming the owner, the first finishes untouched, and a
// lock file left by a dead run is taken over.
TEST(RenderLock, SecondRunIntoTheSameFolderIsRefused) {
  TempDir tmp;
  make_inputs(tmp.path());
  const fs::path lock_file = tmp / "out" / ".raindrop-render.lock";
  {
    Background first(render_args("out"), tmp.path());
    ASSERT_TRUE(first.valid()) << "fork failed";
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (count_newlines(tmp / "out" / "manifest.jsonl") < 1) {
      ASSERT_TRUE(first.running()) << "the first run ended before its first sample; stderr:\n"
                                   << read_file(tmp / "_logs" / "background-stderr");
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "no progress within 120 s";
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(first.running()) << "the first run finished before the second could start";
    const auto second = run_render(render_args("out"), tmp.path());
    EXPECT_EQ(second.code, 1) << second.describe();
    const auto lines = second.message_lines();
    ASSERT_EQ(lines.size(), 1u) << second.describe();
    EXPECT_EQ(lines[0].rfind("raindrop-render: error: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find("in use"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("(pid "), std::string::npos) << lines[0];
    while (first.running()) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline + std::chrono::seconds(120)) << "the first run hangs";
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    const int status = first.kill_now();  // already reaped: its wait status
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
        << "the first run failed; stderr:\n" << read_file(tmp / "_logs" / "background-stderr");
  }
  EXPECT_EQ(manifest_lines(tmp / "out").size(), static_cast<size_t>(kImages * kVariants));
  EXPECT_FALSE(fs::exists(lock_file)) << "the lock is released at the end";
  // A lock file left by a run that died (its pid no longer running) does not block.
  write_file(lock_file, "999999999\n");
  const auto after = run_render(render_args("out"), tmp.path());
  EXPECT_EQ(after.code, 0) << after.describe();
  EXPECT_FALSE(fs::exists(lock_file));
}

}  // namespace
}  // namespace clitest
