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

// `text` in one write() to `file` opened with `flags` (one short line in append mode does not
// interleave with another process's); false, with errno saying why, on failure.
bool write_once(const fs::path& file, int flags, const std::string& text) {
  const int fd = ::open(file.c_str(), flags, 0644);
  if (fd < 0) return false;
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  const int err = errno;
  ::close(fd);
  errno = err;
  return ok;
}

}  // namespace

std::map<std::string, WrittenFile> read_own_outputs(const fs::path& folder) {
  std::map<std::string, WrittenFile> own;
  std::ifstream in(folder / kOwnOutputsList);
  const std::string header(kHeader, std::strlen(kHeader) - 1);
  std::string line;
  // The header is known by its text, not its place: a list whose header could not be written
  // (a full disk) still holds the records appended after it.
  while (std::getline(in, line)) {
    if (in.eof()) break;  // no line break after it: cut short
    if (line == header) continue;
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
  const auto fail = [&list] { throw Error("'" + list.string() + "': cannot write (" + std::strerror(errno) + ")"); };
  // The header once, by whichever run makes the list (O_EXCL: never over another's).
  // O_APPEND: a record another run appended between its creation and this write stays.
  if (!write_once(list, O_WRONLY | O_CREAT | O_EXCL | O_APPEND, kHeader) && errno != EEXIST) fail();
  // A line break first as well: a record cut short by a full disk (a failed run's last) ends
  // there, instead of running into this one and taking it with it.
  const std::string line = "\n" + std::to_string(f.size) + " " + std::to_string(f.mtime_ns) + " " + name + "\n";
  if (!write_once(list, O_WRONLY | O_APPEND, line)) fail();
}

}  // namespace raindrop::cli
