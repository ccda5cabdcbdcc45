// The steady clock in nanoseconds, the unit the engine, the HTTP gate and their statistics
// keep times in.
#pragma once
#include <chrono>
#include <cstdint>

namespace rangex {

inline int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

inline int64_t seconds_ns(double s) {
  return int64_t(s * 1e9);
}

}  // namespace rangex
