#include "raindrop/render/inputs.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>

#include <nlohmann/json.hpp>

#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"

namespace raindrop {
namespace fs = std::filesystem;
namespace {

// The length of the well-formed UTF-8 sequence starting at s[i] (RFC 3629: no overlong forms,
// no surrogates, nothing past U+10FFFF), or 0.
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto byte = [&](std::size_t k) { return k < s.size() ? static_cast<unsigned char>(s[k]) : 0u; };
  const auto cont = [&](std::size_t k, unsigned lo = 0x80, unsigned hi = 0xBF) { return byte(k) >= lo && byte(k) <= hi; };
  const unsigned b = byte(i);
  if (b >= 0xC2 && b <= 0xDF) return cont(i + 1) ? 2 : 0;
  if (b >= 0xE0 && b <= 0xEF) {
    const bool second = b == 0xE0 ? cont(i + 1, 0xA0) : b == 0xED ? cont(i + 1, 0x80, 0x9F) : cont(i + 1);
    return second && cont(i + 2) ? 3 : 0;
  }
  if (b >= 0xF0 && b <= 0xF4) {
    const bool second = b == 0xF0 ? cont(i + 1, 0x90) : b == 0xF4 ? cont(i + 1, 0x80, 0x8F) : cont(i + 1);
    return second && cont(i + 2) && cont(i + 3) ? 4 : 0;
  }
  return 0;
}

// A sample's id as a file name and a JSON string: letters, digits, '-', '_' and '.' stay, and
// so do non-ASCII characters (well-formed UTF-8: "café" stays "café"; replacing each byte with
// '_' made "café" and "cafè" one id, and the run was refused); everything else, bytes that are
// not UTF-8 included, becomes '_'.
std::string safe_id(const std::string& s) {
  std::string id;
  id.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      id += std::isalnum(c) || c == '-' || c == '_' || c == '.' ? static_cast<char>(c) : '_';
      ++i;
    } else if (const std::size_t n = utf8_sequence(s, i)) {
      id.append(s, i, n);
      i += n;
    } else {
      id += '_';
      ++i;
    }
  }
  return id;
}

}  // namespace

Camera read_cityscapes_camera(const fs::path& json_path) {
  std::ifstream in(json_path);
  if (!in) throw Error("'" + json_path.string() + "': cannot read camera file");
  try {
    const auto j = nlohmann::json::parse(in);
    const auto& k = j.at("intrinsic");
    Camera c;
    c.fx = k.at("fx").get<double>();
    c.fy = k.at("fy").get<double>();
    c.cx = k.at("u0").get<double>();
    c.cy = k.at("v0").get<double>();
    if (!(c.fx > 0 && c.fy > 0)) throw Error("'" + json_path.string() + "': focal lengths must be positive");
    return c;
  } catch (const nlohmann::json::exception& e) {
    throw Error("'" + json_path.string() + "': not a Cityscapes camera file (" + e.what() + ")");
  }
}

std::vector<InputImage> find_cityscapes(const fs::path& root, const std::string& split) {
  const fs::path images = root / "leftImg8bit";
  if (!fs::is_directory(images))
    throw Error("'" + root.string() + "' is not a Cityscapes folder: no leftImg8bit/ inside");
  std::vector<std::string> splits;
  if (split == "all") {
    for (const char* s : {"train", "val", "test"}) {
      if (fs::is_directory(images / s)) splits.emplace_back(s);
    }
  } else if (split == "train" || split == "val" || split == "test") {
    if (!fs::is_directory(images / split))
      throw Error("'" + (images / split).string() + "' does not exist (split '" + split + "')");
    splits.push_back(split);
  } else {
    throw Error("split '" + split + "' is not train, val, test or all");
  }
  std::vector<InputImage> out;
  for (const auto& s : splits) {
    std::vector<fs::path> cities;
    for (const auto& e : fs::directory_iterator(images / s)) {
      if (e.is_directory()) cities.push_back(e.path());
    }
    std::sort(cities.begin(), cities.end());
    for (const auto& city : cities) {
      for (const auto& file : list_image_files(city, false)) {
        std::string stem = file.stem().string();
        const std::string suffix = "_leftImg8bit";
        if (stem.size() > suffix.size() && stem.compare(stem.size() - suffix.size(), suffix.size(), suffix) == 0)
          stem.resize(stem.size() - suffix.size());
        InputImage in;
        in.path = file;
        in.id = safe_id(stem);
        in.split = s;
        const fs::path cam = root / "camera" / s / city.filename() / (stem + "_camera.json");
        if (fs::exists(cam)) in.calibration = read_cityscapes_camera(cam);
        out.push_back(std::move(in));
      }
    }
  }
  if (out.empty()) throw Error("no *_leftImg8bit images under '" + images.string() + "' for split '" + split + "'");
  return out;
}

std::vector<InputImage> find_images(const fs::path& source, const std::vector<fs::path>& skip) {
  std::error_code ec;
  if (!fs::exists(source, ec)) throw Error("'" + source.string() + "': no such file or folder");
  std::vector<InputImage> out;
  auto add = [&](const fs::path& file, const std::string& id) {
    InputImage in;
    in.path = file;
    in.id = safe_id(id);
    in.split = "none";
    out.push_back(std::move(in));
  };
  if (fs::is_directory(source)) {
    for (const auto& file : list_image_files(source, true, skip)) {
      // Lexically: fs::relative resolves symbolic links, naming a linked file after its target.
      fs::path rel = file.lexically_relative(source).replace_extension();
      std::string id = rel.generic_string();
      std::replace(id.begin(), id.end(), '/', '-');
      add(file, id);
    }
    if (out.empty()) throw Error("'" + source.string() + "': no image files in this folder");
  } else if (has_image_extension(source)) {
    add(source, source.stem().string());
  } else {
    // A list file: one path per line; blank lines and '#' comments ignored.
    std::ifstream list(source);
    if (!list) throw Error("'" + source.string() + "': cannot read");
    std::string line;
    int n = 0;
    while (std::getline(list, line)) {
      ++n;
      // A binary file (a GIF, a video, a misnamed image) would otherwise be read as paths,
      // and the error would print its bytes as a "file name".
      const auto binary = std::find_if(line.begin(), line.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return (u < 0x20 && c != '\t' && c != '\r') || u == 0x7f;
      });
      if (binary != line.end()) {
        char byte[8];
        std::snprintf(byte, sizeof byte, "0x%02x", static_cast<unsigned char>(*binary));
        throw Error("'" + source.string() + "': not an image by its extension (" + image_extensions() +
                    ") and not a text list of image paths (line " + std::to_string(n) + " holds the binary byte " +
                    byte + ")");
      }
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
      if (line.empty() || line[0] == '#') continue;
      fs::path p = line;
      if (p.is_relative()) p = source.parent_path() / p;
      add(p, p.stem().string());
    }
    if (out.empty()) throw Error("'" + source.string() + "': not an image and lists no images");
  }
  return out;
}

void check_unique_ids(const std::vector<InputImage>& inputs) {
  std::map<std::string, fs::path> seen;
  for (const auto& in : inputs) {
    auto [it, fresh] = seen.emplace(in.id, in.path);
    if (!fresh)
      throw Error("inputs '" + it->second.string() + "' and '" + in.path.string() + "' would both be named '" + in.id + "'");
  }
}

}  // namespace raindrop
