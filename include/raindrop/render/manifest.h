#pragma once
// manifest.jsonl: one JSON object per finished sample (docs/CONTRACTS.md section 1).
// While a run is going, lines are appended as samples finish; at the end the file is
// rewritten sorted by id, so a finished data set's manifest does not depend on thread
// timing. A run that is killed leaves at worst a truncated last line, which the next run
// ignores (and re-renders that sample).
//
// A shard of a run (--shard K/N, shard.h) writes manifest.part-K-of-N.jsonl instead, in the
// same way; the parts merged (merge_manifest_parts) are byte for byte the manifest.jsonl of
// one run.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "raindrop/common/shard.h"

namespace raindrop {

struct ManifestEntry {
  std::string line;  // the JSON object, one line
  std::string job;   // the fingerprint of the settings that produced it
  std::string files[3];  // rainy, clean, mask (relative to the data set folder)
  std::string source;    // the input image it was rendered from, as that run named it
};

// Entries by id. Missing file: empty. A line that is not a record is an error, except a last
// line that is cut: no line break after it and not a whole JSON value (an interrupted append,
// ignored). A whole line that is no record (someone's own notes in a file of that name) is
// an error, so that a resumed run does not replace the file.
std::map<std::string, ManifestEntry> read_manifest(const std::filesystem::path& file);

// "manifest.jsonl" for the whole run, "manifest.part-K-of-N.jsonl" for shard K of N.
std::string manifest_name(const Shard& shard);

// The manifest parts in `dir` (manifest.part-K-of-N.jsonl), with their shard, sorted by name.
std::vector<std::pair<std::filesystem::path, Shard>> find_manifest_parts(const std::filesystem::path& dir);

// Writes the lines (by id) as a finished manifest: sorted by id, one per line, atomically.
void write_manifest(const std::map<std::string, std::string>& lines_by_id, const std::filesystem::path& file);

// Appends records to a manifest as samples finish. Every record in the file ends with its line
// break: a record cut short (an interrupted run's last, which readers ignore) is cut off before
// the first append, and an append that fails (a full disk) is cut off again before the error,
// so that neither is ever followed by a record, which would make it a bad middle line.
class ManifestWriter {
 public:
  explicit ManifestWriter(const std::filesystem::path& file);
  void append(const std::string& id, const std::string& line);  // thread-safe, flushed
  // Rewrites the file sorted by id, from `kept` (earlier runs) plus what was appended.
  void finalize(const std::map<std::string, ManifestEntry>& kept);

 private:
  std::filesystem::path file_;
  std::ofstream out_;
  std::uintmax_t whole_ = 0;  // bytes of whole records in the file
  std::map<std::string, std::string> appended_;
  std::mutex mutex_;
};

}  // namespace raindrop
