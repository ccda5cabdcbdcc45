// What the plant configuration's readers share (plant_config.cpp, lane_config_yaml.cpp,
// learned_detection_yaml.cpp): a YAML node that names its key in every error, and the readers
// that one file's section hands to another's. Included by those files alone, so that yaml-cpp
// stays out of every other unit.
#pragma once
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <initializer_list>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/plant_config.h"

namespace rangex {

// A YAML node with the dotted path that led to it, so that every error names its key.
struct ConfigNode {
  YAML::Node node;
  std::string path;
  const std::string* origin;

  [[noreturn]] void bad(const std::string& why) const {
    if (path.empty()) fail(*origin, ": ", why);
    fail(*origin, ": ", path, ": ", why);
  }

  bool has(const char* key) const { return node.IsMap() && node[key]; }
  ConfigNode at(const std::string& key) const {
    return {node[key], path.empty() ? key : path + "." + key, origin};
  }
  ConfigNode item(size_t i) const {
    return {node[i], path + "[" + std::to_string(i) + "]", origin};
  }

  void only_keys(std::initializer_list<const char*> keys) const {
    if (!node.IsMap()) bad("expected a mapping");
    std::set<std::string> ok(keys.begin(), keys.end()), seen;
    for (const auto& kv : node) {
      // A list or mapping as a key (found by fuzzing) would escape as yaml-cpp's exception.
      if (!kv.first.IsScalar()) bad("has a key that is not a plain name");
      const auto k = kv.first.as<std::string>();
      // YAML parsers keep one of two equal keys silently; a setting written twice is refused.
      if (!seen.insert(k).second) bad("duplicate key '" + k + "'");
      if (!ok.count(k)) {
        std::string list;
        for (const auto& s : ok) list += (list.empty() ? "" : ", ") + s;
        bad("unknown key '" + k + "' (expected: " + list + ")");
      }
    }
  }

  double num() const {
    double v;
    try {
      v = node.as<double>();
    } catch (const YAML::Exception&) {
      bad("expected a number");
    }
    if (!std::isfinite(v)) bad("must be finite");
    return v;
  }
  int integer() const {
    try {
      return node.as<int>();
    } catch (const YAML::Exception&) {
      bad("expected an integer");
    }
  }
  bool boolean() const {
    try {
      return node.as<bool>();
    } catch (const YAML::Exception&) {
      bad("expected true or false");
    }
  }
  std::string str() const {
    if (!node.IsScalar()) bad("expected a string");
    return node.as<std::string>();
  }
  std::vector<double> numbers(size_t n) const {
    if (!node.IsSequence() || node.size() != n)
      bad("expected a list of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (size_t i = 0; i < n; ++i) v.push_back(item(i).num());
    return v;
  }

  // Optional scalar members; absent keys keep the default already in `out`.
  void get(const char* key, double& out) const {
    if (has(key)) out = at(key).num();
  }
  void get(const char* key, int& out) const {
    if (has(key)) out = at(key).integer();
  }
  void get(const char* key, std::string& out) const {
    if (has(key)) out = at(key).str();
  }
  void get(const char* key, bool& out) const {
    if (has(key)) out = at(key).boolean();
  }
  void positive(const char* key, double& out) const {
    get(key, out);
    if (!(out > 0)) at(key).bad("must be > 0");
  }
  void positive(const char* key, int& out) const {
    get(key, out);
    if (out <= 0) at(key).bad("must be > 0");
  }
};

// A list of numbers: `expect` of them, or any number when 0.
std::vector<double> number_list(const ConfigNode& n, size_t expect);

// The text parsed as YAML, refused beyond kMaxYamlBytes or when it is no YAML.
YAML::Node load_yaml(const std::string& text, const std::string& origin);

// A string as a YAML scalar that reads back as itself.
std::string yaml_string(const std::string& s);

// `spread: thickness | fillet`: whether the statistics' spread is measured by thickness.
bool read_spread(const ConfigNode& n);

// inspection.learned, as rangexctl learn writes it (learned_detection_yaml.cpp).
void read_learned(const ConfigNode& n, LearnedDetection& L);

// A lane's `xray` section over `x` (xray_yaml.cpp).
void read_xray(const ConfigNode& n, FanBeam& x);

// A lane's `inspection` section over `q` (inspection_yaml.cpp).
void read_inspection(const ConfigNode& n, InspectionParams& q);

// One lane from its own node over `c`, falling back section by section to lane_defaults
// (lane_config_yaml.cpp).
LaneConfig read_lane(const ConfigNode& lane, const ConfigNode* defaults, LaneConfig c);

// A lane's sensors (`sources`): its own, never in lane_defaults.
void read_sources(const ConfigNode& n, SensorSources& s);

}  // namespace rangex
