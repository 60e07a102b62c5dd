#pragma once
// The small text files beside the models that tune raindrop-remove (a detector router's ROUTER,
// a camera's wet gate): one key and its words per line, '#' starting a comment line.
//
//   # comments
//   format 1
//   mean 0.5 1.25 ...
//
// Read whole and checked here, so that a damaged file is refused in one line naming it.
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "raindrop/common/error.h"

namespace raindrop::removal {

struct KeyFile {
  // How a fault is reported: an Error naming the file, the fault and what to do about it.
  std::function<Error(const std::string& why)> fail;
  std::map<std::string, std::vector<std::string>> fields;

  // The words of `key`; none where the file does not give it.
  const std::vector<std::string>& words(const std::string& key) const;
  // Exactly `count` finite numbers under `key` (with `positive`, each above 0), else fail().
  std::vector<double> numbers(const std::string& key, size_t count, bool positive = false) const;
  // fail() unless the key `format` gives exactly `version`.
  void expect_format(const std::string& version) const;
  // The one folder name under `key` (a name, not a path: ".", ".." and '/' refused), else fail()
  // saying it must name `what`.
  std::string folder_name(const std::string& key, const std::string& what) const;
};

// The largest key file read (ROUTER and gate files are a few hundred bytes).
inline constexpr size_t kMaxKeyFileBytes = 64 * 1024;

// Reads `file` into its fields; fail() where it is not a regular file, is larger than
// kMaxKeyFileBytes, cannot be read or gives a key twice.
KeyFile read_key_file(const std::filesystem::path& file, std::function<Error(const std::string& why)> fail);

}  // namespace raindrop::removal
