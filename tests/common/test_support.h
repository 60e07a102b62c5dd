#pragma once
// What the end-to-end tests of both programs share: temporary folders, files, and running a
// program in a folder with its exit code, stdout and stderr captured.
#include <gtest/gtest.h>

#include <sys/types.h>
#include <sys/wait.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace testsupport {

namespace fs = std::filesystem;

// A fresh folder per test, named after the test, removed afterwards (kept when
// RAINDROP_KEEP_TEST_DIRS is set).
class TempDir {
 public:
  explicit TempDir(const std::string& prefix) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = prefix;
    if (info) name += std::string(info->test_suite_name()) + "-" + info->name() + "-";
    for (char& c : name) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '_';
    }
    std::string templ = (fs::temp_directory_path() / (name + "XXXXXX")).string();
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) throw std::runtime_error("mkdtemp failed for " + templ);
    path_ = fs::path(buf.data());
  }
  ~TempDir() {
    if (std::getenv("RAINDROP_KEEP_TEST_DIRS")) return;
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& rel) const { return path_ / rel; }

 private:
  fs::path path_;
};

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_file(const fs::path& p, const std::string& bytes) {
  if (p.has_parent_path()) fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary);
  out << bytes;
  ASSERT_TRUE(out.good()) << "cannot write " << p;
}

inline std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

struct RunResult {
  int code = -1;  // exit status; -1 if the program did not exit normally
  std::string out, err;
  std::string command;

  std::vector<std::string> err_lines() const { return split_lines(err); }
  std::string describe() const {
    return "command: " + command + "\nexit code: " + std::to_string(code) + "\n--- stdout ---\n" + out +
           "--- stderr ---\n" + err + "--------------";
  }
};

// Runs `prefix program args...` in `cwd` (prefix: shell words such as "env -u NAME ", already
// quoted); stdout and stderr go to files under cwd/_logs and are read back.
inline RunResult run_captured(const fs::path& program, const std::vector<std::string>& args, const fs::path& cwd,
                              const std::string& prefix = "") {
  static int counter = 0;
  const fs::path logs = cwd / "_logs";
  fs::create_directories(logs);
  const std::string tag = std::to_string(counter++);
  const fs::path out_file = logs / ("stdout-" + tag), err_file = logs / ("stderr-" + tag);
  std::string cmd = "cd " + shell_quote(cwd.string()) + " && " + prefix + shell_quote(program.string());
  for (const auto& a : args) cmd += " " + shell_quote(a);
  RunResult r;
  r.command = cmd;
  cmd += " >" + shell_quote(out_file.string()) + " 2>" + shell_quote(err_file.string()) + " </dev/null";
  const int status = std::system(cmd.c_str());
  r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
  r.out = read_file(out_file);
  r.err = read_file(err_file);
  return r;
}

// Runs `prefix program args...` once per argument list in `cwd`, all at the same time (in
// the background of one shell, which waits for them all); the results in the lists' order.
inline std::vector<RunResult> run_captured_together(const fs::path& program,
                                                    const std::vector<std::vector<std::string>>& arg_lists,
                                                    const fs::path& cwd, const std::string& prefix = "") {
  static int counter = 0;
  const fs::path logs = cwd / "_logs";
  fs::create_directories(logs);
  std::vector<RunResult> results(arg_lists.size());
  std::vector<fs::path> bases;
  std::string script = "cd " + shell_quote(cwd.string()) + " && { ";
  for (size_t i = 0; i < arg_lists.size(); ++i) {
    const fs::path base = logs / ("together-" + std::to_string(counter++));
    std::string cmd = prefix + shell_quote(program.string());
    for (const auto& a : arg_lists[i]) cmd += " " + shell_quote(a);
    results[i].command = cmd + " &";
    script += "{ " + cmd + " >" + shell_quote(base.string() + ".out") + " 2>" + shell_quote(base.string() + ".err") +
              " </dev/null; echo $? >" + shell_quote(base.string() + ".code") + "; } & ";
    bases.push_back(base);
  }
  script += "wait; }";
  (void)std::system(script.c_str());
  for (size_t i = 0; i < results.size(); ++i) {
    const std::string code = read_file(bases[i].string() + ".code");
    results[i].code = code.empty() ? -1 : std::stoi(code);
    results[i].out = read_file(bases[i].string() + ".out");
    results[i].err = read_file(bases[i].string() + ".err");
  }
  return results;
}

// Hidden temporaries left by the atomic writes (".<name>.tmp-<pid>-<n>"), relative to `dir`;
// none when `dir` does not exist.
inline std::vector<std::string> hidden_temporaries(const fs::path& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name.find(".tmp-") != std::string::npos)
      found.push_back(fs::relative(it->path(), dir).generic_string());
  }
  return found;
}

// `name` found in a folder of $PATH, or empty. (qemu-x86_64: the tests that run our programs on
// an emulated CPU without VNNI or AVX-512 skip where it is absent.)
inline fs::path find_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    std::error_code ec;
    if (!dir.empty() && fs::is_regular_file(fs::path(dir) / name, ec)) return fs::path(dir) / name;
  }
  return {};
}

}  // namespace testsupport
