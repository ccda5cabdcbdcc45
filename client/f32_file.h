// The raw float images `rangexctl process` writes beside a recording (stripe_cam*.f32,
// thickness.f32): read back by the commands that re-use them.
#pragma once

#include <cstddef>
#include <filesystem>
#include <vector>

namespace rangex::cli {

// The `expect` floats of file `p`; fails naming the file when it is missing or of another
// size.
std::vector<float> read_f32(const std::filesystem::path& p, size_t expect);

}  // namespace rangex::cli
