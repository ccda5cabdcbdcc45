// 16-bit and 8-bit grayscale PNG writing (thickness in 0.01 mm, X-ray counts, overlays), and
// reading.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

void write_png16(const std::string& path, const uint16_t* pixels, int width, int height);
void write_png8(const std::string& path, const uint8_t* pixels, int width, int height,
                int channels = 1);
// An 8-bit PNG in memory (served over HTTP).
std::string encode_png8(const uint8_t* pixels, int width, int height, int channels = 1);
// A 16-bit grayscale PNG as written by write_png16; throws Error naming the file otherwise.
std::vector<uint16_t> read_png16(const std::string& path, int& width, int& height);
// Any PNG as 8-bit gray (a camera's calibration images): palette and low depths expanded,
// 16 bits rounded to 8, alpha dropped, colour weighted as ITU-R BT.601.
std::vector<uint8_t> read_png8_gray(const std::string& path, int& width, int& height);

}  // namespace rangex
