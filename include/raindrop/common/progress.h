#pragma once
// A thread-safe progress bar on stderr: done/total, rate, ETA. On a terminal it redraws one
// line; otherwise (logs, CI) it prints a line at most every 10% or 30 seconds.
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace raindrop {

class Progress {
 public:
  Progress(std::int64_t total, std::string label, bool enabled);
  void advance(std::int64_t n = 1);
  void finish();

 private:
  void draw(bool final_line);
  std::int64_t total_, done_ = 0, last_printed_ = -1;
  std::string label_;
  bool enabled_, tty_, finished_ = false;
  std::chrono::steady_clock::time_point start_, last_draw_;
  std::mutex mutex_;
};

}  // namespace raindrop
