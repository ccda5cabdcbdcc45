// PNG reading against what was written: 16-bit grayscale back exactly, and any PNG as the
// 8-bit gray a camera's calibration images are read as (16 bits rounded to 8, colour by the
// weights of ITU-R BT.601); files that are not PNG are refused naming the file.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "core/error.h"
#include "core/png_io.h"
#include "temp_dir.h"

using namespace rangex;

namespace {
// An 8-bit gray PNG written by libpng itself, interlaced (Adam7) or not.
void write_gray8(const std::string& path, const std::vector<uint8_t>& px, int w, int h,
                 bool interlaced) {
  FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_init_io(png, f);
  png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_GRAY,
               interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const int passes = png_set_interlace_handling(png);
  for (int p = 0; p < passes; ++p)
    for (int y = 0; y < h; ++y) png_write_row(png, px.data() + size_t(y) * w);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  std::fclose(f);
}

// A hostile file: a valid header claiming w x h gray pixels and the start of an image data
// chunk (where a reader learns the size), then nothing.
void write_claim(const std::string& path, uint32_t w, uint32_t h) {
  auto crc = [](const std::string& bytes) {  // CRC-32 as PNG's chunks carry it
    uint32_t c = 0xffffffffu;
    for (unsigned char b : bytes) {
      c ^= b;
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return c ^ 0xffffffffu;
  };
  auto be32 = [](uint32_t v) {
    return std::string{char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
  };
  const std::string ihdr = "IHDR" + be32(w) + be32(h) + std::string{8, 0, 0, 0, 0};
  std::ofstream(path, std::ios::binary)
      << "\x89PNG\r\n\x1a\n"
      << be32(13) << ihdr << be32(crc(ihdr)) << be32(100) << "IDAT";
}
// What reading `path` as 8-bit gray fails with.
std::string error_of(const std::string& path) {
  int w = 0, h = 0;
  try {
    read_png8_gray(path, w, h);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

TEST(PngIo, SixteenBitGrayReadsBackExactly) {
  test::TempDir t;
  const int w = 5, h = 3;
  std::vector<uint16_t> px(w * h);
  for (int i = 0; i < w * h; ++i) px[i] = uint16_t(i * 4099 + 1);
  write_png16(t.str("a.png"), px.data(), w, h);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_png16(t.str("a.png"), rw, rh), px);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
}

TEST(PngIo, AnyPngReadsAsEightBitGray) {
  test::TempDir t;
  const int w = 4, h = 2;
  // 8-bit gray: as written.
  const std::vector<uint8_t> g8 = {0, 1, 2, 127, 128, 200, 254, 255};
  write_png8(t.str("g8.png"), g8.data(), w, h);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_png8_gray(t.str("g8.png"), rw, rh), g8);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
  // 16-bit gray: v 255 / 65535, rounded.
  const std::vector<uint16_t> g16 = {0, 128, 129, 257, 32767, 32896, 65407, 65535};
  write_png16(t.str("g16.png"), g16.data(), w, h);
  const std::vector<uint8_t> r16 = read_png8_gray(t.str("g16.png"), rw, rh);
  ASSERT_EQ(r16.size(), g16.size());
  for (size_t i = 0; i < g16.size(); ++i)
    EXPECT_EQ(r16[i], int(std::lround(g16[i] * 255.0 / 65535))) << g16[i];
  // Colour: 0.299 R + 0.587 G + 0.114 B (libpng's fixed point: within one level).
  const std::vector<uint8_t> rgb = {255, 0,   0,   0,   255, 0,  0,  0,  255, 255, 255, 255,
                                    10,  200, 100, 250, 30,  60, 90, 90, 90,  0,   0,   0};
  write_png8(t.str("rgb.png"), rgb.data(), w, h, 3);
  const std::vector<uint8_t> rg = read_png8_gray(t.str("rgb.png"), rw, rh);
  ASSERT_EQ(rg.size(), size_t(w * h));
  for (int i = 0; i < w * h; ++i) {
    const double y = 0.299 * rgb[3 * i] + 0.587 * rgb[3 * i + 1] + 0.114 * rgb[3 * i + 2];
    EXPECT_NEAR(rg[i], y, 1.0) << "pixel " << i;
  }
}

TEST(PngIo, WhatIsNotAPngIsRefusedNamingTheFile) {
  test::TempDir t;
  std::ofstream(t.str("x.png")) << "not a png at all";
  EXPECT_NE(error_of(t.str("x.png")).find("x.png: not a readable PNG"), std::string::npos)
      << error_of(t.str("x.png"));
  EXPECT_NE(error_of(t.str("missing.png")).find("missing.png: cannot open"), std::string::npos)
      << error_of(t.str("missing.png"));
  // An 8-bit image where 16 bits are expected.
  const std::vector<uint8_t> g8(4, 7);
  write_png8(t.str("g8.png"), g8.data(), 2, 2);
  int w = 0, h = 0;
  EXPECT_THROW(read_png16(t.str("g8.png"), w, h), Error);
}

TEST(PngIo, InterlacedImagesReadWhole) {
  test::TempDir t;
  const int w = 13, h = 9;  // not a multiple of Adam7's 8x8 blocks
  std::vector<uint8_t> px(w * h);
  for (int i = 0; i < w * h; ++i) px[i] = uint8_t(i * 37 + 11);
  write_gray8(t.str("i.png"), px, w, h, true);
  int rw = 0, rh = 0;
  EXPECT_EQ(read_png8_gray(t.str("i.png"), rw, rh), px);
  EXPECT_EQ(rw, w);
  EXPECT_EQ(rh, h);
}

TEST(PngIo, AHeaderClaimingAHugeImageIsRefusedBeforeItIsAllocated) {
  test::TempDir t;
  write_claim(t.str("huge.png"), 100000, 100000);  // 10^10 pixels
  EXPECT_NE(error_of(t.str("huge.png")).find("huge.png: 100000x100000 pixels, more than"),
            std::string::npos)
      << error_of(t.str("huge.png"));
}
