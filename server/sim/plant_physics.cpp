#include "sim/plant_physics.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "core/error.h"

namespace rangex::sim {

namespace {

// One section of the variant: reads keys into fields, refusing unknown keys and values
// outside [lo, hi] by their full name.
class Section {
 public:
  Section(const YAML::Node& root, const std::string& name, const std::string& origin)
      : node_(root[name]), name_(name), origin_(origin) {
    if (node_ && !node_.IsMap()) fail(origin_, ": ", name_, ": expected a map");
  }
  Section& num(const char* key, double& out, double lo, double hi) {
    seen_.insert(key);
    if (!node_ || !node_[key]) return *this;
    double v = 0;
    try {
      v = node_[key].as<double>();
    } catch (const YAML::Exception&) {
      fail(origin_, ": ", name_, ".", key, ": expected a number");
    }
    if (!(v >= lo && v <= hi))
      fail(origin_, ": ", name_, ".", key, ": must be within ", lo, "..", hi, " (got ", v, ")");
    out = v;
    return *this;
  }
  void done() const {
    if (!node_) return;
    for (const auto& kv : node_) {
      const std::string k = kv.first.as<std::string>();
      if (!seen_.count(k)) fail(origin_, ": ", name_, ": unknown key '", k, "'");
    }
  }

 private:
  YAML::Node node_;
  std::string name_, origin_;
  std::set<std::string> seen_;
};

}  // namespace

PlantPhysics parse_plant_physics(const std::string& yaml, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& e) {
    fail(origin, ": not valid YAML: ", e.what());
  }
  PlantPhysics p;
  if (!root || root.IsNull()) return p;
  if (!root.IsMap()) fail(origin, ": expected a map of sections");
  static const std::set<std::string> kSections = {
      "name", "held_out", "xray", "laser", "scatter", "speckle", "shapes", "bones", "belt", "meat"};
  for (const auto& kv : root)
    if (!kSections.count(kv.first.as<std::string>()))
      fail(origin, ": unknown section '", kv.first.as<std::string>(), "'");
  if (root["name"]) p.name = root["name"].as<std::string>();
  if (root["held_out"]) {
    try {
      p.held_out = root["held_out"].as<bool>();
    } catch (const YAML::Exception&) {
      fail(origin, ": held_out: expected true or false");
    }
  }
  Section(root, "xray", origin)
      .num("detector_sigma_px", p.xray.detector_sigma_px, 0, 10)
      .num("focal_spot_sigma_mm", p.xray.focal_spot_sigma_mm, 0, 5)
      .num("plane_offset_lines", p.xray.plane_offset_lines, -0.5, 0.5)
      .num("alpha_deg", p.xray.alpha_deg, -2, 2)
      .num("beta_deg", p.xray.beta_deg, -2, 2)
      .num("hardening", p.xray.hardening, 0, 5)
      .num("flat_field_std", p.xray.flat_field_std, 0, 0.05)
      .num("ripple", p.xray.ripple, 0, 0.05)
      .num("ripple_lines", p.xray.ripple_lines, 2, 100000)
      .done();
  Section(root, "meat", origin)
      .num("texture_std", p.meat.texture_std, 0, 0.2)
      .num("marbling", p.meat.marbling, 0, 0.5)
      .num("marbling_contrast", p.meat.marbling_contrast, 0, 0.6)
      .num("fat_share_min", p.meat.fat_share_min, 0, 0.9)
      .num("fat_share_max", p.meat.fat_share_max, 0, 0.9)
      .done();
  if (p.meat.fat_share_min > p.meat.fat_share_max)
    fail(origin, ": meat.fat_share_min (", p.meat.fat_share_min, ") exceeds fat_share_max (",
         p.meat.fat_share_max, ")");
  Section(root, "laser", origin)
      .num("core_sigma_px", p.laser.core_sigma_px, 0.3, 5)
      .num("defocus_px_per_mm", p.laser.defocus_px_per_mm, 0, 0.2)
      .done();
  double direction = p.scatter.direction;
  Section(root, "scatter", origin)
      .num("tail_base", p.scatter.tail_base, 0, 2)
      .num("tail_gain", p.scatter.tail_gain, 0, 2)
      .num("tail_px", p.scatter.tail_px, 0.2, 20)
      .num("direction", direction, -1, 1)
      .num("spread", p.scatter.spread, 0, 1.5)
      .done();
  if (direction != 1 && direction != -1) fail(origin, ": scatter.direction: must be 1 or -1");
  p.scatter.direction = int(direction);
  Section(root, "speckle", origin)
      .num("pixel", p.speckle.pixel, 0, 1)
      .num("column", p.speckle.column, 0, 1)
      .num("correlation_px", p.speckle.correlation_px, 0, 20)
      .num("glint_probability", p.speckle.glint_probability, 0, 0.2)
      .done();
  Section(root, "shapes", origin)
      .num("steep_fraction", p.shapes.steep_fraction, 0, 1)
      .num("flap_probability", p.shapes.flap_probability, 0, 1)
      .num("fold_probability", p.shapes.fold_probability, 0, 1)
      .num("touching_probability", p.shapes.touching_probability, 0, 1)
      .done();
  Section(root, "bones", origin)
      .num("probability", p.bones.probability, 0, 1)
      .num("needle", p.bones.needle, 0, 1)
      .num("chip", p.bones.chip, 0, 1)
      .num("rib", p.bones.rib, 0, 1)
      .num("cluster", p.bones.cluster, 0, 1)
      .num("calcification_min", p.bones.calcification_min, 0.05, 1)
      .num("calcification_max", p.bones.calcification_max, 0.05, 1)
      .num("cartilage_probability", p.bones.cartilage_probability, 0, 1)
      .done();
  if (p.bones.needle + p.bones.chip + p.bones.rib + p.bones.cluster > 1 + 1e-9)
    fail(origin, ": bones: the shares of needle, chip, rib and cluster add up to more than 1");
  if (p.bones.calcification_min > p.bones.calcification_max)
    fail(origin, ": bones: calcification_min is above calcification_max");
  Section(root, "belt", origin)
      .num("dropped_line_rate", p.belt.dropped_line_rate, 0, 0.1)
      .num("debris_probability", p.belt.debris_probability, 0, 1)
      .num("texture", p.belt.texture, 0, 0.9)
      .num("encoder_jitter_mm", p.belt.encoder_jitter_mm, 0, 1)
      .done();
  return p;
}

PlantPhysics load_plant_physics(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_plant_physics(ss.str(), path);
}

std::string to_yaml(const PlantPhysics& p) {
  std::ostringstream o;
  o.precision(10);
  const auto& x = p.xray;
  o << "name: " << p.name << "\nheld_out: " << (p.held_out ? "true" : "false")
    << "\nxray: {detector_sigma_px: " << x.detector_sigma_px
    << ", focal_spot_sigma_mm: " << x.focal_spot_sigma_mm
    << ", plane_offset_lines: " << x.plane_offset_lines << ", alpha_deg: " << x.alpha_deg
    << ", beta_deg: " << x.beta_deg << ", hardening: " << x.hardening
    << ", flat_field_std: " << x.flat_field_std << ", ripple: " << x.ripple
    << ", ripple_lines: " << x.ripple_lines << "}\n"
    << "laser: {core_sigma_px: " << p.laser.core_sigma_px
    << ", defocus_px_per_mm: " << p.laser.defocus_px_per_mm << "}\n"
    << "scatter: {tail_base: " << p.scatter.tail_base << ", tail_gain: " << p.scatter.tail_gain
    << ", tail_px: " << p.scatter.tail_px << ", direction: " << p.scatter.direction
    << ", spread: " << p.scatter.spread << "}\n"
    << "speckle: {pixel: " << p.speckle.pixel << ", column: " << p.speckle.column
    << ", correlation_px: " << p.speckle.correlation_px
    << ", glint_probability: " << p.speckle.glint_probability << "}\n"
    << "shapes: {steep_fraction: " << p.shapes.steep_fraction
    << ", flap_probability: " << p.shapes.flap_probability
    << ", fold_probability: " << p.shapes.fold_probability
    << ", touching_probability: " << p.shapes.touching_probability << "}\n"
    << "bones: {probability: " << p.bones.probability << ", needle: " << p.bones.needle
    << ", chip: " << p.bones.chip << ", rib: " << p.bones.rib << ", cluster: " << p.bones.cluster
    << ", calcification_min: " << p.bones.calcification_min
    << ", calcification_max: " << p.bones.calcification_max
    << ", cartilage_probability: " << p.bones.cartilage_probability << "}\n"
    << "belt: {dropped_line_rate: " << p.belt.dropped_line_rate
    << ", debris_probability: " << p.belt.debris_probability << ", texture: " << p.belt.texture
    << ", encoder_jitter_mm: " << p.belt.encoder_jitter_mm << "}\n"
    << "meat: {texture_std: " << p.meat.texture_std << ", marbling: " << p.meat.marbling
    << ", marbling_contrast: " << p.meat.marbling_contrast
    << ", fat_share_min: " << p.meat.fat_share_min << ", fat_share_max: " << p.meat.fat_share_max
    << "}\n";
  return o.str();
}

}  // namespace rangex::sim
