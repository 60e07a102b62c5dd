#include "raindrop/common/image_files.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <string_view>

#include "raindrop/common/error.h"

namespace raindrop {
namespace fs = std::filesystem;
namespace {

// What OpenImageIO reads and both programs handle, sorted (image_extensions lists them so).
constexpr std::array<std::string_view, 8> kExtensions = {".bmp", ".exr",  ".jpeg", ".jpg",
                                                         ".png", ".tif", ".tiff", ".webp"};

}  // namespace

fs::path canonical_form(const fs::path& p) {
  fs::path c = fs::weakly_canonical(fs::absolute(p));
  return c.has_filename() ? c : c.parent_path();  // "dir/" is "dir"
}

bool is_under(const fs::path& p, const fs::path& dir) {
  const auto rel = canonical_form(p).lexically_relative(canonical_form(dir));
  return !rel.empty() && *rel.begin() != "..";
}

bool strictly_inside(const fs::path& p, const fs::path& dir) {
  const auto rel = canonical_form(p).lexically_relative(canonical_form(dir));
  return !rel.empty() && rel != "." && *rel.begin() != "..";
}

std::string lowercase_extension(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool has_image_extension(const fs::path& p) {
  const std::string ext = lowercase_extension(p);
  return std::find(kExtensions.begin(), kExtensions.end(), ext) != kExtensions.end();
}

bool is_image_name(const fs::path& p) {
  const std::string name = p.filename().string();
  return !name.empty() && name[0] != '.' && has_image_extension(p);
}

std::string image_extensions() {
  std::string all;
  for (const auto e : kExtensions) all += (all.empty() ? "" : ", ") + std::string(e.substr(1));
  return all;
}

namespace {

// An entry's type without the throwing overloads: a symbolic link loop (or one whose target
// cannot be examined) is neither a folder nor a file to read, instead of stopping the walk of
// the whole folder.
bool is_directory(const fs::directory_entry& e) {
  std::error_code ec;
  return e.is_directory(ec);
}
bool is_symlink(const fs::directory_entry& e) {
  std::error_code ec;
  return e.is_symlink(ec);
}
bool is_regular_file(const fs::directory_entry& e) {
  std::error_code ec;
  return e.is_regular_file(ec);
}

}  // namespace

std::vector<fs::path> list_image_files(const fs::path& dir, bool recursive, const std::vector<fs::path>& skip,
                                      std::vector<fs::path>* unfollowed) {
  std::vector<fs::path> files;
  std::error_code ec;
  // Only folders strictly inside `dir` are left out: a skip folder that is `dir` itself or
  // holds it (an output folder given as the input folder or its parent) would otherwise
  // leave out every subfolder, silently.
  std::vector<fs::path> inside;
  for (const fs::path& s : skip) {
    if (!s.empty() && strictly_inside(s, dir)) inside.push_back(s);
  }
  const auto skipped = [&](const fs::path& p) {
    return std::any_of(inside.begin(), inside.end(), [&](const fs::path& s) { return is_under(p, s); });
  };
  if (recursive) {
    for (auto it = fs::recursive_directory_iterator(dir, fs::directory_options::skip_permission_denied, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      if (is_directory(*it) && skipped(it->path())) {
        it.disable_recursion_pending();
        continue;
      }
      if (unfollowed && is_symlink(*it) && is_directory(*it)) unfollowed->push_back(it->path());
      if (is_regular_file(*it) && is_image_name(it->path())) files.push_back(it->path());
    }
  } else {
    for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
      if (unfollowed && is_symlink(*it) && is_directory(*it)) unfollowed->push_back(it->path());
      if (is_regular_file(*it) && is_image_name(it->path())) files.push_back(it->path());
    }
  }
  if (ec) throw Error("cannot list " + quoted(dir) + " (" + ec.message() + ")");
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace raindrop
