// A whole text file as a string; Error naming the file (and `hint`, why it should be there)
// when it cannot be read.
#pragma once
#include <string>

namespace rangex {

std::string read_text_file(const std::string& path, const std::string& hint = "");

}  // namespace rangex
