// A zip archive of one file, laid out as GenICam devices ship their descriptions: a local
// header and the data (raw deflate, or stored), one central directory entry, the end record.
#pragma once
#include <zlib.h>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace rangex::test {

// Field offsets a test changes to make an archive lie (APPNOTE 4.3.7, 4.3.12, 4.3.16).
struct ZipLayout {
  size_t local = 0, data = 0, entry = 0, end = 0;
};

inline void zip_put(std::string& z, size_t at, uint64_t v, int bytes) {
  for (int b = 0; b < bytes; ++b) z[at + b] = char(uint8_t(v >> (8 * b)));
}

inline std::string zip_archive(const std::string& name, const std::string& data, bool deflated,
                               ZipLayout* layout = nullptr) {
  std::string packed = data;
  if (deflated) {
    z_stream zs{};
    if (deflateInit2(&zs, 9, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK)
      throw std::runtime_error("deflateInit2");
    packed.assign(deflateBound(&zs, uLong(data.size())), '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    zs.avail_in = uInt(data.size());
    zs.next_out = reinterpret_cast<Bytef*>(packed.data());
    zs.avail_out = uInt(packed.size());
    if (::deflate(&zs, Z_FINISH) != Z_STREAM_END) throw std::runtime_error("deflate");
    packed.resize(zs.total_out);
    deflateEnd(&zs);
  }
  const uint32_t crc =
      uint32_t(crc32(0, reinterpret_cast<const Bytef*>(data.data()), uInt(data.size())));
  // The fields a local header and a directory entry share, from the method on (at 8 and 10).
  const auto file_fields = [&](std::string& h, size_t at) {
    zip_put(h, at, deflated ? 8 : 0, 2);
    zip_put(h, at + 6, crc, 4);
    zip_put(h, at + 10, packed.size(), 4);
    zip_put(h, at + 14, data.size(), 4);
    zip_put(h, at + 18, name.size(), 2);
  };
  ZipLayout l;
  std::string z(30, '\0');
  zip_put(z, 0, 0x04034b50, 4);
  zip_put(z, 4, 20, 2);
  file_fields(z, 8);
  z += name;
  l.data = z.size();
  z += packed;
  l.entry = z.size();
  std::string e(46, '\0');
  zip_put(e, 0, 0x02014b50, 4);
  zip_put(e, 4, 20, 2);
  zip_put(e, 6, 20, 2);
  file_fields(e, 10);
  zip_put(e, 42, 0, 4);  // the local header's offset
  z += e + name;
  l.end = z.size();
  std::string end(22, '\0');
  zip_put(end, 0, 0x06054b50, 4);
  zip_put(end, 8, 1, 2);
  zip_put(end, 10, 1, 2);
  zip_put(end, 12, 46 + name.size(), 4);
  zip_put(end, 16, l.entry, 4);
  z += end;
  if (layout) *layout = l;
  return z;
}

}  // namespace rangex::test
