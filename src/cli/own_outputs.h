#pragma once
// Which files in a folder raindrop-remove itself wrote, so that a later run may replace them
// and nothing else.
//
// An output or mask folder that holds the input, or lies inside it, may also hold the user's
// own photographs (photos/2023/ as the output of photos/, or photos/ as the output of
// photos/wet/). There a run replaces a file only if an earlier run wrote it: the folder's
// hidden list (kOwnOutputsList) names, one per line, every file written there. A folder-wide
// mark was not enough: written once into a folder that already held the user's photographs,
// it let every later run replace them.
#include <filesystem>
#include <set>
#include <string>

namespace raindrop::cli {

inline constexpr const char* kOwnOutputsList = ".raindrop-remove-outputs";

// The names (relative to `folder`, generic form: "sub/a.png") that `folder`'s list holds;
// empty when there is no list. A list from before the names were kept (its first line only)
// names nothing, so its folder's files are protected like any others.
std::set<std::string> read_own_outputs(const std::filesystem::path& folder);

// Adds `names` to `folder`'s list (written whole to a temporary, then renamed over it).
// Called before the files are written: a run cut short leaves names whose files were not
// written, which protect nothing and harm nothing.
void add_own_outputs(const std::filesystem::path& folder, const std::set<std::string>& names);

}  // namespace raindrop::cli
