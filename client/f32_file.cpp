#include "f32_file.h"

#include <fstream>

#include "core/error.h"

namespace rangex::cli {

std::vector<float> read_f32(const std::filesystem::path& p, size_t expect) {
  namespace fs = std::filesystem;
  if (!fs::exists(p))
    fail(p.string(), " is missing (was the output written by 'rangexctl process'?)");
  if (fs::file_size(p) != expect * sizeof(float))
    fail(p.string(), " holds ", fs::file_size(p), " bytes, expected ", expect * sizeof(float));
  std::vector<float> v(expect);
  std::ifstream in(p, std::ios::binary);
  if (!in.read(reinterpret_cast<char*>(v.data()), std::streamsize(expect * sizeof(float))))
    fail(p.string(), ": could not be read");
  return v;
}

}  // namespace rangex::cli
