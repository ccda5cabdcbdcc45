#include "core/text_file.h"

#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangex {

std::string read_text_file(const std::string& path, const std::string& hint) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open", hint.empty() ? "" : " (" + hint + ")");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace rangex
