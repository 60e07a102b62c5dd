#pragma once
// One exception type for every user-facing failure (bad input, unwritable output, bad scene
// file). Command-line front ends catch it and print its message as a single line.
#include <stdexcept>
#include <string>

namespace raindrop {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace raindrop
