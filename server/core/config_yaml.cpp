#include "core/config_yaml.h"

#include <algorithm>
#include <cstdio>

#include "core/size_limits.h"
#include "core/utf8.h"

namespace rangex {

std::vector<double> number_list(const ConfigNode& n, size_t expect) {
  if (!n.node.IsSequence()) n.bad("expected a list of numbers");
  return n.numbers(expect ? expect : n.node.size());
}

YAML::Node load_yaml(const std::string& text, const std::string& origin) {
  check_size(origin, text.size(), kMaxYamlBytes);
  if (const size_t at = invalid_utf8_at(text); at != std::string::npos) {
    char byte[8];
    std::snprintf(byte, sizeof byte, "0x%02X", unsigned(static_cast<unsigned char>(text[at])));
    fail(origin, ": line ", 1 + std::count(text.begin(), text.begin() + long(at), '\n'), ": byte ",
         byte, " is not UTF-8 (YAML is Unicode text: write names and notes in UTF-8)");
  }
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail(origin, ": not valid YAML: ", e.what());
  }
}

// A string as a YAML scalar that reads back as itself (found by fuzzing: a camera name or a
// fitted_on note with a quote or a line break was written as is, and the stored calibration
// no longer read back).
std::string yaml_string(const std::string& s) {
  YAML::Emitter e;
  e << YAML::DoubleQuoted << s;
  return e.c_str();
}

}  // namespace rangex
