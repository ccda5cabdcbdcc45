// A plant's physics as the simulator renders it, each effect a named part, so that a plant
// variant is a YAML file (config/variants/*.yaml). Every default is the nominal simulator:
// an empty file renders exactly what `rangexctl simulate` rendered before variants existed.
#pragma once
#include <string>

namespace rangex::sim {

struct XrayPhysics {
  double detector_sigma_px = 0;    // the detector's line-spread function (Gaussian)
  double focal_spot_sigma_mm = 0;  // the source's size across the fan
  // The X-ray plane against the laser's: a fraction of a line beyond the configured delay,
  // turned about the vertical (alpha) and the lateral axis (beta).
  double plane_offset_lines = 0, alpha_deg = 0, beta_deg = 0;
  // Beam hardening: the effective attenuation falls with path length,
  // mu_eff = mu / (1 + hardening * mu * L) (a polychromatic beam's harder tail).
  double hardening = 0;
  // What a flat-field correction leaves: a fixed gain pattern across the detector (relative
  // std per pixel); and the source's ripple: the tube's output varying along the belt by
  // this fraction with a period of ripple_lines lines.
  double flat_field_std = 0;
  double ripple = 0, ripple_lines = 37;
};

struct LaserPhysics {
  double core_sigma_px = 1.1;    // the laser line's width in the image at focus
  double defocus_px_per_mm = 0;  // extra core sigma per mm of height above the belt
};

struct ScatterPhysics {
  double tail_base = 0.12, tail_gain = 0.45, tail_px = 2.5;  // CameraRenderParams' meat tail
  // +1: the scattered light leaves on the side away from the camera (the nominal model,
  // shifting the stripe one way); -1: toward it (the other way, as another meat does).
  int direction = 1;
  double spread = 0;  // per fillet, the tail's size varies by exp(spread * N(0,1)) (fat, skin)
};

struct SpeckleNoise {
  double pixel = 0.15, column = 0.10;  // multiplicative std, as CameraRenderParams
  double correlation_px = 0;           // along a column: 0 independent, else AR(1) of that length
  double glint_probability = 0;        // a meat column glints (a wet spot): far brighter, narrower
};

struct FilletShapes {
  double steep_fraction = 0;          // fillets with near-vertical walls (several mm in one pixel)
  double flap_probability = 0;        // a thin flap (2-4 mm) grown from one side
  double fold_probability = 0;        // a folded end: a second layer over part of the fillet
  double touching_probability = 0.2;  // the next fillet almost touches (the nominal gap rule)
};

struct BoneShapes {
  double probability = 0.5;  // a fillet holds bone
  // Shares of the fragment shapes (the rest compact ellipsoids, the nominal shape):
  // needles (long, 0.3-0.8 mm thick, at any orientation), flat chips, curved rib pieces,
  // clusters of small pieces.
  double needle = 0, chip = 0, rib = 0, cluster = 0;
  double calcification_min = 0.3, calcification_max = 1.0;
  double cartilage_probability = 0;  // cartilage or tendon: denser than meat, not bone
};

// Meat as rough as real meat (sim/meat_texture.h): attenuation texture and fat marbling.
struct MeatPhysics {
  double texture_std = 0;
  double marbling = 0;
  double marbling_contrast = 0.15;
  // Dual energy renders the meat as lean and fat (ICRU muscle and adipose tissue): each
  // fillet's fat share of its meat is drawn within these (the marbling's streaks add theirs).
  double fat_share_min = 0.02, fat_share_max = 0.10;
};

struct BeltPhysics {
  double dropped_line_rate = 0;   // camera lines lost on the way (a whole line, both cameras)
  double debris_probability = 0;  // small bits of meat between fillets
  double texture = 0;             // the belt's reflectance varies by this much (weave, water)
  double encoder_jitter_mm = 0;   // where a line is really taken against its encoder count
};

struct PlantPhysics {
  std::string name = "nominal";
  bool held_out = false;  // kept out of the development loop: report, never tune on it
  XrayPhysics xray;
  LaserPhysics laser;
  ScatterPhysics scatter;
  SpeckleNoise speckle;
  FilletShapes shapes;
  BoneShapes bones;
  BeltPhysics belt;
  MeatPhysics meat;
};

// Parses a variant; unknown keys, NaN and out-of-range values are refused naming the key.
PlantPhysics parse_plant_physics(const std::string& yaml, const std::string& origin);
PlantPhysics load_plant_physics(const std::string& path);
std::string to_yaml(const PlantPhysics& p);

}  // namespace rangex::sim
