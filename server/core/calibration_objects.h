// The machined calibration objects an integrator places on a lane (Laser Range Imaging §6.4): the
// CNC staircase of Table 5, the X-ray pin phantom of Figure 27 and the registration blocks of
// §6.4.3, as their drawings give them (YAML). The solvers take these as known; the
// simulator builds its scenes from them.
#pragma once
#include <string>
#include <vector>

namespace rangex {

struct Staircase {
  std::vector<double> heights_mm{5, 10, 15, 20, 25, 30, 35, 40, 45, 50};  // along +x
  double step_width_mm = 12;
  double length_mm = 60;   // along the belt
  double x0_mm = -60;      // left wall of the first step (the block stands against a fence)
  double lead_in_mm = 30;  // belt before the block in a scan
};

struct PinPhantom {
  struct Row {
    double z_mm;
    std::vector<double> x_mm;
  };
  std::vector<Row> rows;  // in the order they reach the X-ray plane
  double radius_mm = 0.5;
  double pin_length_mm = 8;  // along the belt
  double row_pitch_mm = 20;  // along the belt, row to row
  double lead_in_mm = 30;
  // Figure 27's design, taller: rows at 10..90 mm (the source height is seen in how the
  // magnification changes with height), pins every 10 mm from -70 to 70 mm.
  static PinPhantom figure27();
};

// Blocks of known size at unknown places (the registration measures where they are).
struct BlockSet {
  struct Block {
    double width_mm, length_mm, height_mm;  // across, along the belt, up
  };
  std::vector<Block> blocks;  // in the order they pass the planes
  double gap_mm = 40;         // at least this much belt between blocks
  double lead_in_mm = 30;
  static BlockSet standard();  // five blocks from 5 to 50 mm high
};

std::string to_yaml(const Staircase& s);
std::string to_yaml(const PinPhantom& p);
std::string to_yaml(const BlockSet& b);
// Parse what to_yaml writes; refuse (naming the key) NaN, non-positive sizes, empty lists.
Staircase parse_staircase(const std::string& yaml, const std::string& origin);
PinPhantom parse_pin_phantom(const std::string& yaml, const std::string& origin);
BlockSet parse_block_set(const std::string& yaml, const std::string& origin);

}  // namespace rangex
