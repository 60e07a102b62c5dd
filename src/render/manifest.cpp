#include "raindrop/render/manifest.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iterator>

#include <nlohmann/json.hpp>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"

namespace raindrop {
namespace fs = std::filesystem;

std::map<std::string, ManifestEntry> read_manifest(const fs::path& file) {
  std::map<std::string, ManifestEntry> entries;
  std::ifstream in(file);
  if (!in) return entries;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) continue;
    const std::string bad = "'" + file.string() + "' line " + std::to_string(number) + " is not a manifest record (";
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(line);
    } catch (const nlohmann::json::exception& ex) {
      // Only the last line, cut short (no line break after it), is an interrupted append: ignored.
      if (in.eof()) break;
      throw Error(bad + ex.what() + ")");
    }
    try {
      ManifestEntry e;
      e.line = line;
      e.job = j.value("job", "");
      e.source = j.value("source", "");
      e.files[0] = j.at("rainy").get<std::string>();
      e.files[1] = j.at("clean").get<std::string>();
      e.files[2] = j.at("mask").get<std::string>();
      entries[j.at("id").get<std::string>()] = std::move(e);
    } catch (const nlohmann::json::exception& ex) {
      // Whole JSON that is no record: an append cut short is never a whole value.
      throw Error(bad + ex.what() + "); is this folder a data set raindrop-render wrote?");
    }
  }
  return entries;
}

std::string manifest_name(const Shard& shard) {
  if (!shard.sharded()) return "manifest.jsonl";
  return "manifest.part-" + std::to_string(shard.index) + "-of-" + std::to_string(shard.count) + ".jsonl";
}

std::vector<std::pair<fs::path, Shard>> find_manifest_parts(const fs::path& dir) {
  std::vector<std::pair<fs::path, Shard>> parts;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    Shard s;
    char tail = 0;
    if (std::sscanf(name.c_str(), "manifest.part-%d-of-%d.jsonl%c", &s.index, &s.count, &tail) == 2 &&
        s.count > 1 && s.index >= 0 && s.index < s.count && name == manifest_name(s))
      parts.emplace_back(it->path(), s);
  }
  std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return parts;
}

void write_manifest(const std::map<std::string, std::string>& lines_by_id, const fs::path& file) {
  check_replaceable(file);  // a manifest made read-only is kept (image_io.h)
  std::string text;
  for (const auto& [id, line] : lines_by_id) text += line + "\n";
  write_text_atomic(text, file);
}

ManifestWriter::ManifestWriter(const fs::path& file) : file_(file) {
  {
    // The whole records already there: up to the last line break.
    std::ifstream in(file, std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t end = text.rfind('\n');
    whole_ = end == std::string::npos ? 0 : end + 1;
    if (whole_ < text.size()) {
      std::error_code ec;
      fs::resize_file(file, whole_, ec);
      if (ec) throw Error("'" + file.string() + "': cannot cut off its last record, cut short (" + ec.message() + ")");
    }
  }
  out_.open(file, std::ios::app);
  if (!out_) throw Error("'" + file.string() + "': cannot open for writing");
}

void ManifestWriter::append(const std::string& id, const std::string& line) {
  std::lock_guard<std::mutex> lock(mutex_);
  out_ << line << '\n';
  out_.flush();
  if (!out_) {
    const int err = errno;
    out_.close();
    std::error_code ec;
    fs::resize_file(file_, whole_, ec);  // the part written, if any: readers would take it for a record
    throw Error("'" + file_.string() + "': write failed (" + std::strerror(err) + ")");
  }
  whole_ += line.size() + 1;
  appended_[id] = line;
}

void ManifestWriter::finalize(const std::map<std::string, ManifestEntry>& kept) {
  std::lock_guard<std::mutex> lock(mutex_);
  out_.close();
  std::map<std::string, std::string> all;
  for (const auto& [id, e] : kept) all[id] = e.line;
  for (const auto& [id, line] : appended_) all[id] = line;
  write_manifest(all, file_);
}

}  // namespace raindrop
