#include "core/png_io.h"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

#include "core/error.h"

namespace rangex {

namespace {
std::string io_reason(int err) {
  return err == ENOSPC ? std::string("disk full (") + std::strerror(err) + ")" : std::strerror(err);
}
// Written beside its place and renamed into it: a reader, or a store that lost power or
// space halfway, sees the whole image or none.
void write_png(const std::string& path, const uint8_t* rows, int width, int height, int depth,
               int color, size_t stride) {
  const std::string part = path + ".part";
  FILE* f = std::fopen(part.c_str(), "wb");
  if (!f) fail(path, ": cannot create (", io_reason(errno), ")");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    const int err = errno;
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    std::remove(part.c_str());
    fail(path, ": cannot write (", err ? io_reason(err) : std::string("PNG encoding failed"), ")");
  }
  errno = 0;
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
  const bool flushed = std::fflush(f) == 0 && !std::ferror(f);
  const int err = errno;
  if (std::fclose(f) != 0 || !flushed) {
    const int e = err ? err : errno;
    std::remove(part.c_str());
    fail(path, ": cannot write (", io_reason(e), ")");
  }
  if (std::rename(part.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(part.c_str());
    fail(path, ": cannot rename into place (", io_reason(e), ")");
  }
}
void append_to_string(png_structp png, png_bytep data, png_size_t n) {
  static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<char*>(data), n);
}
void no_flush(png_structp) {}
}  // namespace

std::string encode_png8(const uint8_t* pixels, int width, int height, int channels) {
  std::string out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    fail("PNG encoding failed");
  }
  png_set_write_fn(png, &out, append_to_string, no_flush);
  png_set_IHDR(png, info, width, height, 8,
               channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, 3);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y)
    png_write_row(png, const_cast<png_bytep>(pixels + size_t(width) * channels * size_t(y)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

std::vector<uint16_t> read_png16(const std::string& path, int& width, int& height) {
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail(path, ": cannot open (", std::strerror(errno), ")");
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  std::vector<uint16_t> out;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(f);
    fail(path, ": not a readable PNG");
  }
  png_init_io(png, f);
  png_read_info(png, info);
  const int depth = png_get_bit_depth(png, info), color = png_get_color_type(png, info);
  if (depth != 16 || color != PNG_COLOR_TYPE_GRAY) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(f);
    fail(path, ": expected a 16-bit grayscale PNG (depth ", depth, ", color type ", color, ")");
  }
  width = int(png_get_image_width(png, info));
  height = int(png_get_image_height(png, info));
  png_set_swap(png);  // to host order
  out.resize(size_t(width) * size_t(height));
  for (int y = 0; y < height; ++y)
    png_read_row(png, reinterpret_cast<png_bytep>(&out[size_t(y) * size_t(width)]), nullptr);
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  std::fclose(f);
  return out;
}

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
