// Finding and opening raindrop_oiio.so (oiio_codec.h says why it is a plugin).
#include <dlfcn.h>
#include <unistd.h>

#include <climits>
#include <cstdlib>
#include <mutex>
#include <vector>

#include "oiio_codec.h"
#include "raindrop/common/error.h"

namespace raindrop::oiio {
namespace fs = std::filesystem;
namespace {

fs::path program_folder() {
  char buffer[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buffer, sizeof buffer - 1);
  if (n <= 0) return {};
  return fs::path(std::string(buffer, static_cast<size_t>(n))).parent_path();
}

struct Loaded {
  const Codec* codec = nullptr;
  std::string failure;
};

Loaded load() {
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("RAINDROP_OIIO_PLUGIN"); env && *env) {
    std::error_code ec;
    candidates.push_back(fs::absolute(env, ec));  // absolute: dlopen must not search the library path
  } else if (const fs::path here = program_folder(); !here.empty()) {
    candidates = {here / kPluginName, here / ".." / "lib" / "raindrop" / kPluginName};
  } else {
    return {nullptr, "the program's own folder is unknown (/proc/self/exe); set RAINDROP_OIIO_PLUGIN"};
  }
  std::string tried;
  for (const auto& path : candidates) {
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      tried += (tried.empty() ? "" : ", ") + quoted(path) + " not found";
      continue;
    }
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) return {nullptr, one_line(::dlerror())};
    auto entry = reinterpret_cast<const Codec* (*)()>(::dlsym(handle, kEntryPoint));
    if (!entry) return {nullptr, quoted(path) + " is from another build of raindrop (it has no " + kEntryPoint + ")"};
    const Codec* codec = entry();
    if (!codec || codec->interface != kInterface)
      return {nullptr, quoted(path) + " is from another build of raindrop (interface " +
                           std::to_string(codec ? codec->interface : -1) + ", this program needs " +
                           std::to_string(kInterface) + ")"};
    return {codec, ""};
  }
  return {nullptr, tried};
}

}  // namespace

const Codec& codec(const std::string& what) {
  static std::once_flag once;
  static Loaded loaded;
  std::call_once(once, [] { loaded = load(); });
  if (!loaded.codec) throw Error(what + " needs OpenImageIO, whose plugin did not load (" + loaded.failure + ")");
  return *loaded.codec;
}

}  // namespace raindrop::oiio
