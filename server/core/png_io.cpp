#include "core/png_io.h"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

#include "core/error.h"

namespace rangex {

namespace {
void write_png(const std::string& path, const uint8_t* rows, int width, int height, int depth,
               int color, size_t stride) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) fail(path, ": cannot create (", std::strerror(errno), ")");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    fail(path, ": PNG encoding failed");
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, width, height, depth, color, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 3);
  png_write_info(png, info);
  if (depth == 16) png_set_swap(png);  // PNG is big-endian; our buffers are host order
  for (int y = 0; y < height; ++y)
    png_write_row(png, const_cast<png_bytep>(rows + stride * size_t(y)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fclose(f) != 0) fail(path, ": write failed");
}
}  // namespace

void write_png16(const std::string& path, const uint16_t* pixels, int width, int height) {
  write_png(path, reinterpret_cast<const uint8_t*>(pixels), width, height, 16, PNG_COLOR_TYPE_GRAY,
            size_t(width) * 2);
}

void write_png8(const std::string& path, const uint8_t* pixels, int width, int height,
                int channels) {
  write_png(path, pixels, width, height, 8,
            channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, size_t(width) * channels);
}

}  // namespace rangex
