#include "core/config_yaml.h"

#include "core/size_limits.h"

namespace rangex {

std::vector<double> number_list(const ConfigNode& n, size_t expect) {
  if (!n.node.IsSequence()) n.bad("expected a list of numbers");
  return n.numbers(expect ? expect : n.node.size());
}

YAML::Node load_yaml(const std::string& text, const std::string& origin) {
  check_size(origin, text.size(), kMaxYamlBytes);
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
