// Test frames for stripe extraction: stripes with a Gaussian core and a one-sided
// exponential tail over a noisy background, written independently of the simulator, plus
// the awkward columns every path must treat as the reference does (glare, saturation, no
// stripe, a flat top, peaks on the first and last rows).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace rangex::test {

struct Frames {
  int count, width, height;
  std::vector<uint8_t> px;
  uint8_t& at(int f, int y, int c) { return px[(size_t(f) * height + y) * width + c]; }
};

inline Frames make_frames(int count, int width, int height, unsigned seed) {
  Frames fr{count, width, height, std::vector<uint8_t>(size_t(count) * width * height)};
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int f = 0; f < count; ++f)
    for (int c = 0; c < width; ++c) {
      const double centre = 3 + u(rng) * (height - 6), amp = 30 + u(rng) * 260;
      const double sigma = 0.7 + u(rng) * 1.3, tail = u(rng) * 0.5, decay = 1 + u(rng) * 3;
      for (int y = 0; y < height; ++y) {
        const double d = y - centre;
        double g = 10 + noise(rng) + amp * std::exp(-0.5 * d * d / (sigma * sigma));
        if (d > 0) g += amp * tail * std::exp(-d / decay);
        fr.at(f, y, c) = uint8_t(std::clamp(std::lround(g), 0L, 255L));
      }
    }
  for (int f = 0; f < count; ++f) {
    const int h = height;
    for (int y = h / 8; y < h / 8 + std::min(h / 2, 60); ++y)
      fr.at(f, y, 7 % width) = 230;                                         // glare
    for (int y = h / 2; y < h / 2 + 4; ++y) fr.at(f, y, 33 % width) = 255;  // saturated
    for (int y = 0; y < h; ++y) fr.at(f, y, 64 % width) = 9;                // no stripe
    for (int y = h / 3; y < h / 3 + 3; ++y) fr.at(f, y, 70 % width) = 150;  // flat top
    fr.at(f, 0, 100 % width) = 250;                                         // peak on row 0
    fr.at(f, h - 1, 101 % width) = 250;                                     // on the last row
  }
  return fr;
}

}  // namespace rangex::test
