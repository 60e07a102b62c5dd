#pragma once
// manifest.jsonl: one JSON object per finished sample (docs/CONTRACTS.md section 1).
// While a run is going, lines are appended as samples finish; at the end the file is
// rewritten sorted by id, so a finished data set's manifest does not depend on thread
// timing. A run that is killed leaves at worst a truncated last line, which the next run
// ignores (and re-renders that sample).
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>

namespace raindrop {

struct ManifestEntry {
  std::string line;  // the JSON object, one line
  std::string job;   // the fingerprint of the settings that produced it
  std::string files[3];  // rainy, clean, mask (relative to the data set folder)
};

// Entries by id. Missing file: empty. A line that does not parse is an error unless it is
// the last line (an interrupted append).
std::map<std::string, ManifestEntry> read_manifest(const std::filesystem::path& file);

class ManifestWriter {
 public:
  explicit ManifestWriter(const std::filesystem::path& file);
  void append(const std::string& id, const std::string& line);  // thread-safe, flushed
  // Rewrites the file sorted by id, from `kept` (earlier runs) plus what was appended.
  void finalize(const std::map<std::string, ManifestEntry>& kept);

 private:
  std::filesystem::path file_;
  std::ofstream out_;
  std::map<std::string, std::string> appended_;
  std::mutex mutex_;
};

}  // namespace raindrop
