#pragma once
// Command-line conventions shared by raindrop-render, raindrop-remove and raindrop-bench:
// image sizes are WIDTHxHEIGHT everywhere (as OpenCV's cv::Size and image tools write them),
// and a choice among names is parsed by CLI11 straight into its enum, so a bad value is
// CLI11's usage error (exit 2) before anything runs.
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <type_traits>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

namespace raindrop::cli {

// "512x256" -> 512 wide, 256 high, each side in [min_side, max_side]; nullopt if malformed.
inline std::optional<cv::Size> parse_width_height(const std::string& text, int min_side = 1, int max_side = 16384) {
  int w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < min_side || h < min_side || w > max_side ||
      h > max_side)
    return std::nullopt;
  return cv::Size(w, h);
}

// The first of `names` given with an empty value ("--mask ''"), which CLI11 stores as if the
// option had not been given (no mask, the default models, every shard); nullopt if none was.
inline std::optional<std::string> option_given_empty(CLI::App& app, std::initializer_list<const char*> names) {
  for (const char* name : names) {
    if (app.count(name) > 0 && app.get_option(name)->as<std::string>().empty()) return std::string(name);
  }
  return std::nullopt;
}

// A validator for string options that hold a WIDTHxHEIGHT size; with `allow_empty`, an empty
// value passes too ("none", as the option says).
inline CLI::Validator width_height(int min_side = 1, int max_side = 16384, bool allow_empty = false) {
  return CLI::Validator(
      [=](const std::string& text) -> std::string {
        if ((allow_empty && text.empty()) || parse_width_height(text, min_side, max_side)) return {};
        return "'" + text + "' must be WIDTHxHEIGHT with sides " + std::to_string(min_side) + " to " +
               std::to_string(max_side) + ", e.g. 512x256";
      },
      "WxH");
}

// A validator for an unsigned 64-bit option (a seed): digits only, 0 to 2^64 - 1. CLI11's own
// conversion wraps "-1" to 2^64 - 1 and clamps a number past the top to it, both silently.
inline CLI::Validator unsigned_64(const std::string& what) {
  return CLI::Validator(
      [what](const std::string& text) -> std::string {
        std::uint64_t value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, value);
        if (text.empty() || ec != std::errc() || ptr != end)
          return "'" + text + "' is not a whole number from 0 to 18446744073709551615 (2^64 - 1)" +
                 (what.empty() ? "" : " (" + what + ")");
        return {};
      },
      "UINT64");
}

// Parses an option's value by name straight into an enum: exact names only (not the enum's
// numbers), listed in --help and in the error.
template <class Enum>
CLI::Validator names_to(const std::map<std::string, Enum>& names) {
  std::string list;
  for (const auto& entry : names) list += (list.empty() ? "" : ",") + entry.first;
  return CLI::Validator(
      [names, list](std::string& text) -> std::string {
        const auto it = names.find(text);
        if (it == names.end()) return "'" + text + "' is not one of {" + list + "}";
        text = std::to_string(static_cast<std::underlying_type_t<Enum>>(it->second));  // what CLI11 converts
        return {};
      },
      "{" + list + "}");
}

}  // namespace raindrop::cli
