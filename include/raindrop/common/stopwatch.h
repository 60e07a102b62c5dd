#pragma once
// Wall-clock timing of pipeline stages (renderer, remover, benchmarks): milliseconds on the
// monotonic clock, which no clock adjustment can move backwards.
#include <chrono>

namespace raindrop {

using Clock = std::chrono::steady_clock;

// Milliseconds since `start`.
inline double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Milliseconds since `lap_start`, which then restarts: times consecutive stages with one clock.
inline double lap_ms(Clock::time_point& lap_start) {
  const auto now = Clock::now();
  const double ms = std::chrono::duration<double, std::milli>(now - lap_start).count();
  lap_start = now;
  return ms;
}

}  // namespace raindrop
