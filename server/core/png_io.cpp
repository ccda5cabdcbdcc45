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

namespace {
constexpr uint64_t kMaxPixels = uint64_t(1) << 28;

// The libpng state of one file being read, released however the reading ends.
struct PngRead {
  FILE* f = nullptr;
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~PngRead() {
    png_destroy_read_struct(&png, &info, nullptr);
    if (f) std::fclose(f);
  }
};

// Reads the PNG at `path` into one T per pixel: `transform` checks the header (failing with
// a message) and sets the libpng transforms that give those pixels.
template <typename T, typename Transform>
std::vector<T> read_png(const std::string& path, int& width, int& height, Transform transform) {
  PngRead r;
  r.f = std::fopen(path.c_str(), "rb");
  if (!r.f) fail(path, ": cannot open (", std::strerror(errno), ")");
  r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  r.info = r.png ? png_create_info_struct(r.png) : nullptr;
  std::vector<T> out;
  if (!r.png || !r.info || setjmp(png_jmpbuf(r.png))) fail(path, ": not a readable PNG");
  png_init_io(r.png, r.f);
  png_read_info(r.png, r.info);
  transform(r.png, r.info);
  const int passes = png_set_interlace_handling(r.png);  // 7 for Adam7, else 1
  png_read_update_info(r.png, r.info);
  width = int(png_get_image_width(r.png, r.info));
  height = int(png_get_image_height(r.png, r.info));
  if (png_get_rowbytes(r.png, r.info) != size_t(width) * sizeof(T))
    fail(path, ": not one ", 8 * sizeof(T), "-bit sample a pixel after conversion");
  // A header may claim any size up to libpng's limits: refused before it is allocated.
  if (uint64_t(width) * uint64_t(height) > kMaxPixels)
    fail(path, ": ", width, "x", height, " pixels, more than the ", kMaxPixels, " read");
  out.resize(size_t(width) * size_t(height));
  for (int pass = 0; pass < passes; ++pass)
    for (int y = 0; y < height; ++y)
      png_read_row(r.png, reinterpret_cast<png_bytep>(&out[size_t(y) * size_t(width)]), nullptr);
  png_read_end(r.png, nullptr);
  return out;
}
}  // namespace

std::vector<uint16_t> read_png16(const std::string& path, int& width, int& height) {
  return read_png<uint16_t>(path, width, height, [&](png_structp png, png_infop info) {
    const int depth = png_get_bit_depth(png, info), color = png_get_color_type(png, info);
    if (depth != 16 || color != PNG_COLOR_TYPE_GRAY)
      fail(path, ": expected a 16-bit grayscale PNG (depth ", depth, ", color type ", color, ")");
    png_set_swap(png);  // to host order
  });
}

std::vector<uint8_t> read_png8_gray(const std::string& path, int& width, int& height) {
  return read_png<uint8_t>(path, width, height, [](png_structp png, png_infop info) {
    const int color = png_get_color_type(png, info);
    if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (color == PNG_COLOR_TYPE_GRAY) png_set_expand_gray_1_2_4_to_8(png);
    png_set_scale_16(png);  // 16 bits to 8, rounded
    png_set_strip_alpha(png);
    // Colour to gray with the weights of ITU-R BT.601 (OpenCV's, the reader this replaces).
    if (color & PNG_COLOR_MASK_COLOR || color == PNG_COLOR_TYPE_PALETTE)
      png_set_rgb_to_gray(png, PNG_ERROR_ACTION_NONE, 0.299, 0.587);
  });
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
