#include "progress_bar.h"

#include <unistd.h>

#include <cstdio>

namespace rangex::cli {

ProgressBar::ProgressBar(std::string label)
    : label_(std::move(label)), tty_(isatty(2)), start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() {
  if (drawn_) std::fprintf(stderr, "\n");
}

void ProgressBar::update(int64_t done, int64_t total) {
  if (!tty_ || total <= 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (drawn_ && done < total && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  drawn_ = true;
  const double f = double(done) / double(total);
  const double el = std::chrono::duration<double>(now - start_).count();
  const int width = 30, fill = int(f * width);
  std::string bar(fill, '#');
  bar.resize(width, '.');
  const double eta = f > 0 ? el * (1 - f) / f : 0;
  std::fprintf(stderr, "\r%-10s [%s] %5.1f%%  %lld/%lld  %4.0fs left ", label_.c_str(), bar.c_str(),
               100 * f, (long long)done, (long long)total, eta);
  std::fflush(stderr);
}

}  // namespace rangex::cli
