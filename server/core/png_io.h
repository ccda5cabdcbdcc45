// 16-bit and 8-bit grayscale PNG writing (thickness in 0.01 mm, X-ray counts, overlays).
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

void write_png16(const std::string& path, const uint16_t* pixels, int width, int height);
void write_png8(const std::string& path, const uint8_t* pixels, int width, int height,
                int channels = 1);

}  // namespace rangex
