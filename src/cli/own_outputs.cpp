#include "own_outputs.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "raindrop/common/error.h"

namespace raindrop::cli {
namespace fs = std::filesystem;

namespace {

constexpr const char* kHeader =
    "raindrop-remove wrote the files below (size, modification time in ns, name); a later run may replace "
    "them while they are unchanged, and no other file here.\n";

// The file's own record (lstat: a link is not followed), or nothing for anything but a regular file.
bool stat_regular(const fs::path& file, WrittenFile& out) {
  struct stat st {};
  if (::lstat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  out.size = static_cast<std::uintmax_t>(st.st_size);
  out.mtime_ns = static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  return true;
}

}  // namespace

std::map<std::string, WrittenFile> read_own_outputs(const fs::path& folder) {
  std::map<std::string, WrittenFile> own;
  std::ifstream in(folder / kOwnOutputsList);
  std::string line;
  if (!std::getline(in, line)) return own;  // no list (or an empty one)
  while (std::getline(in, line)) {
    if (in.eof()) break;  // no line break after it: cut short
    std::istringstream fields(line);
    WrittenFile f;
    std::string name;
    if (!(fields >> f.size >> f.mtime_ns) || fields.get() != ' ' || !std::getline(fields, name) || name.empty())
      continue;
    own[name] = f;
  }
  return own;
}

bool is_own_output(const std::map<std::string, WrittenFile>& own, const std::string& name, const fs::path& file) {
  const auto it = own.find(name);
  WrittenFile now;
  return it != own.end() && stat_regular(file, now) && now.size == it->second.size && now.mtime_ns == it->second.mtime_ns;
}

void record_own_output(const fs::path& folder, const std::string& name, const fs::path& file) {
  WrittenFile f;
  if (name.find_first_of("\r\n") != std::string::npos || !stat_regular(file, f)) return;
  const fs::path list = folder / kOwnOutputsList;
  // The header once, by whichever run makes the list (O_EXCL: never over another's).
  const int made = ::open(list.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (made >= 0) {
    const bool ok = ::write(made, kHeader, std::strlen(kHeader)) == static_cast<ssize_t>(std::strlen(kHeader));
    ::close(made);
    if (!ok) throw Error("'" + list.string() + "': cannot write (" + std::strerror(errno) + ")");
  } else if (errno != EEXIST) {
    throw Error("'" + list.string() + "': cannot write (" + std::strerror(errno) + ")");
  }
  const std::string line = std::to_string(f.size) + " " + std::to_string(f.mtime_ns) + " " + name + "\n";
  const int fd = ::open(list.c_str(), O_WRONLY | O_APPEND);
  const bool ok = fd >= 0 && ::write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  const int err = errno;
  if (fd >= 0) ::close(fd);
  if (!ok) throw Error("'" + list.string() + "': cannot write (" + std::strerror(err) + ")");
}

}  // namespace raindrop::cli
