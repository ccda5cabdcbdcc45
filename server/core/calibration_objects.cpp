#include "core/calibration_objects.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "core/error.h"

namespace rangex {

PinPhantom PinPhantom::figure27() {
  PinPhantom p;
  for (int z = 10; z <= 90; z += 10) {
    PinPhantom::Row r{double(z), {}};
    for (int x = -70; x <= 70; x += 10) r.x_mm.push_back(x);
    p.rows.push_back(r);
  }
  return p;
}

BlockSet BlockSet::standard() {
  BlockSet b;
  b.blocks = {{40, 30, 5}, {60, 50, 20}, {30, 40, 35}, {50, 60, 50}, {70, 35, 12}};
  return b;
}

namespace {

std::string list(const std::vector<double>& v) {
  std::ostringstream o;
  o << "[";
  for (size_t i = 0; i < v.size(); ++i) o << (i ? ", " : "") << v[i];
  return o.str() + "]";
}

struct Reader {
  YAML::Node root;
  std::string origin;
  Reader(const std::string& text, const std::string& o, const char* key) : origin(o) {
    try {
      root = YAML::Load(text)[key];
    } catch (const YAML::Exception& e) {
      fail(origin, ": ", e.what());
    }
    if (!root || !root.IsMap()) fail(origin, ": expected a mapping '", key, "'");
  }
  double number(const YAML::Node& n, const std::string& key, bool positive = true) const {
    double v;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(origin, ": ", key, ": expected a number");
    }
    if (!std::isfinite(v)) fail(origin, ": ", key, ": not a finite number");
    if (positive && !(v > 0)) fail(origin, ": ", key, ": must be > 0");
    return v;
  }
  void get(const char* key, double& out, bool positive = true) const {
    if (root[key]) out = number(root[key], key, positive);
  }
  std::vector<double> numbers(const YAML::Node& n, const std::string& key, bool positive) const {
    if (!n || !n.IsSequence() || n.size() == 0) fail(origin, ": ", key, ": expected a list");
    std::vector<double> v;
    for (size_t i = 0; i < n.size(); ++i)
      v.push_back(number(n[i], key + "[" + std::to_string(i) + "]", positive));
    return v;
  }
};

}  // namespace

std::string to_yaml(const Staircase& s) {
  std::ostringstream o;
  o << "staircase:\n  heights_mm: " << list(s.heights_mm)
    << "\n  step_width_mm: " << s.step_width_mm << "\n  length_mm: " << s.length_mm
    << "\n  x0_mm: " << s.x0_mm << "\n  lead_in_mm: " << s.lead_in_mm << "\n";
  return o.str();
}

std::string to_yaml(const PinPhantom& p) {
  std::ostringstream o;
  o << "pin_phantom:\n  radius_mm: " << p.radius_mm << "\n  pin_length_mm: " << p.pin_length_mm
    << "\n  row_pitch_mm: " << p.row_pitch_mm << "\n  lead_in_mm: " << p.lead_in_mm
    << "\n  rows:\n";
  for (const auto& r : p.rows)
    o << "    - {z_mm: " << r.z_mm << ", x_mm: " << list(r.x_mm) << "}\n";
  return o.str();
}

std::string to_yaml(const BlockSet& b) {
  std::ostringstream o;
  o << "blocks:\n  gap_mm: " << b.gap_mm << "\n  lead_in_mm: " << b.lead_in_mm << "\n  list:\n";
  for (const auto& k : b.blocks)
    o << "    - {width_mm: " << k.width_mm << ", length_mm: " << k.length_mm
      << ", height_mm: " << k.height_mm << "}\n";
  return o.str();
}

Staircase parse_staircase(const std::string& text, const std::string& origin) {
  const Reader r(text, origin, "staircase");
  Staircase s;
  s.heights_mm = r.numbers(r.root["heights_mm"], "staircase.heights_mm", true);
  r.get("step_width_mm", s.step_width_mm);
  r.get("length_mm", s.length_mm);
  r.get("x0_mm", s.x0_mm, false);
  r.get("lead_in_mm", s.lead_in_mm);
  return s;
}

PinPhantom parse_pin_phantom(const std::string& text, const std::string& origin) {
  const Reader r(text, origin, "pin_phantom");
  PinPhantom p;
  r.get("radius_mm", p.radius_mm);
  r.get("pin_length_mm", p.pin_length_mm);
  r.get("row_pitch_mm", p.row_pitch_mm);
  r.get("lead_in_mm", p.lead_in_mm);
  const YAML::Node rows = r.root["rows"];
  if (!rows || !rows.IsSequence() || rows.size() == 0)
    fail(origin, ": pin_phantom.rows: expected a list of rows");
  for (size_t i = 0; i < rows.size(); ++i) {
    const std::string key = "pin_phantom.rows[" + std::to_string(i) + "]";
    PinPhantom::Row row;
    row.z_mm = r.number(rows[i]["z_mm"], key + ".z_mm");
    row.x_mm = r.numbers(rows[i]["x_mm"], key + ".x_mm", false);
    p.rows.push_back(row);
  }
  return p;
}

BlockSet parse_block_set(const std::string& text, const std::string& origin) {
  const Reader r(text, origin, "blocks");
  BlockSet b;
  r.get("gap_mm", b.gap_mm);
  r.get("lead_in_mm", b.lead_in_mm);
  const YAML::Node l = r.root["list"];
  if (!l || !l.IsSequence() || l.size() == 0) fail(origin, ": blocks.list: expected a list");
  for (size_t i = 0; i < l.size(); ++i) {
    const std::string key = "blocks.list[" + std::to_string(i) + "]";
    b.blocks.push_back({r.number(l[i]["width_mm"], key + ".width_mm"),
                        r.number(l[i]["length_mm"], key + ".length_mm"),
                        r.number(l[i]["height_mm"], key + ".height_mm")});
  }
  return b;
}

}  // namespace rangex
