// Polls `pred` until it holds or `seconds` pass: the bound for a test that could hang.
#pragma once
#include <chrono>
#include <thread>

namespace rangex::test {

template <typename Pred>
bool wait_until(double seconds, Pred pred) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return pred();
}

}  // namespace rangex::test
