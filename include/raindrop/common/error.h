#pragma once
// One exception type for every user-facing failure (bad input, unwritable output, bad scene
// file). Command-line front ends catch it and print its message as a single line.
#include <filesystem>
#include <stdexcept>
#include <string>

namespace raindrop {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Any message as one line: newlines become spaces, surrounding space is trimmed. Command-line
// programs print every error through this (library messages, e.g. OpenCV's, can span lines).
inline std::string one_line(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  const auto first = text.find_first_not_of(' ');
  const auto last = text.find_last_not_of(' ');
  return first == std::string::npos ? std::string("unknown error") : text.substr(first, last - first + 1);
}

// A file's name as error messages show it: in single quotes, so that spaces and empty names
// are visible.
inline std::string quoted(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

}  // namespace raindrop
