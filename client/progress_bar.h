// A progress bar on stderr when it is a terminal; silent otherwise (logs stay clean).
#pragma once
#include <chrono>
#include <cstdint>
#include <string>

namespace rangex::cli {

class ProgressBar {
 public:
  explicit ProgressBar(std::string label);
  ~ProgressBar();
  void update(int64_t done, int64_t total);

 private:
  std::string label_;
  bool tty_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace rangex::cli
