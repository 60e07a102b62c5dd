#include "raindrop/remove/key_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace raindrop::removal {

const std::vector<std::string>& KeyFile::words(const std::string& key) const {
  static const std::vector<std::string> none;
  const auto it = fields.find(key);
  return it == fields.end() ? none : it->second;
}

std::vector<double> KeyFile::numbers(const std::string& key, size_t count, bool positive) const {
  const auto& given = words(key);
  if (given.size() != count) throw fail("'" + key + "' must hold " + std::to_string(count) + " number" + (count > 1 ? "s" : ""));
  std::vector<double> v;
  for (const std::string& w : given) {
    char* end = nullptr;
    errno = 0;
    const double d = std::strtod(w.c_str(), &end);
    if (end == w.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(d))
      throw fail("'" + key + "' holds '" + w + "', not a finite number");
    v.push_back(d);
  }
  if (positive && std::any_of(v.begin(), v.end(), [](double d) { return !(d > 0); }))
    throw fail("'" + key + "' must hold positive numbers");
  return v;
}

void KeyFile::expect_format(const std::string& version) const {
  if (words("format") != std::vector<std::string>{version}) throw fail("expected 'format " + version + "'");
}

std::string KeyFile::folder_name(const std::string& key, const std::string& what) const {
  const auto& given = words(key);
  if (given.size() != 1 || given[0] == "." || given[0] == ".." || given[0].find('/') != std::string::npos)
    throw fail("'" + key + "' must name " + what);
  return given[0];
}

KeyFile read_key_file(const std::filesystem::path& file, std::function<Error(const std::string& why)> fail) {
  KeyFile kf{std::move(fail), {}};
  // A few hundred bytes in practice. A FIFO or a device (--wet-gate /dev/zero) would block or
  // grow without end, so only a regular file is opened, and at most kMaxKeyFileBytes read.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw kf.fail("not a file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw kf.fail("cannot read it");
  std::string text(kMaxKeyFileBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (in.bad()) throw kf.fail("cannot read it");
  text.resize(static_cast<size_t>(in.gcount()));
  if (text.size() > kMaxKeyFileBytes)
    throw kf.fail("larger than " + std::to_string(kMaxKeyFileBytes / 1024) + " KiB: not a key file");
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::string key, word;
    if (!(words >> key) || key[0] == '#') continue;
    if (kf.fields.count(key)) throw kf.fail("'" + key + "' is given twice");
    auto& values = kf.fields[key];
    while (words >> word) values.push_back(word);
  }
  return kf;
}

}  // namespace raindrop::removal
