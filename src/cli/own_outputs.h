#pragma once
// Which files in a folder raindrop-remove itself wrote, so that a later run may replace them
// and nothing else.
//
// An output or mask folder that holds the input, or lies inside it, may also hold the user's
// own photographs (photos/2023/ as the output of photos/, or photos/ as the output of
// photos/wet/). There a run replaces a file only if an earlier run wrote it and it has not
// changed since: the folder's hidden list (kOwnOutputsList) records each file written there
// with its size and modification time. Two weaker forms failed: a folder-wide mark, written
// once into a folder that already held the user's photographs, let every later run replace
// them; a list of names alone let a run replace a photograph the user had put where an earlier
// output of the same name had been.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

namespace raindrop::cli {

inline constexpr const char* kOwnOutputsList = ".raindrop-remove-outputs";

// A file as this program wrote it.
struct WrittenFile {
  std::uintmax_t size = 0;
  std::int64_t mtime_ns = 0;
};

// The records of `folder`'s list by name (relative to `folder`, generic form: "sub/a.png"),
// the last one of a name winning; empty when there is no list. Lines that are not records (a
// list from before the records, a line cut short) count for nothing: their files stay protected.
std::map<std::string, WrittenFile> read_own_outputs(const std::filesystem::path& folder);

// Whether `file` is what `own` records for `name`: a regular file (not a link) of the recorded
// size and modification time.
bool is_own_output(const std::map<std::string, WrittenFile>& own, const std::string& name,
                   const std::filesystem::path& file);

// Appends `file`'s record, as it is now, under `name` to `folder`'s list (one short line after
// a line break, one write in append mode, so that shards writing into one folder do not
// interleave). A name with a line break is not recorded: its file stays protected. Throws
// raindrop::Error if the list cannot be written (the caller removes the file it could not record).
void record_own_output(const std::filesystem::path& folder, const std::string& name, const std::filesystem::path& file);

}  // namespace raindrop::cli
