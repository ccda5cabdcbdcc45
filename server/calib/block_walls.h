// Where each block of a registration scan stands, as each plane sees it (Laser Range Imaging
// §6.4.3): the lines at which its leading and trailing walls cross each plane, its side walls in
// the X-ray, and each camera's view of its top. The blocks stand askew, so a wall crosses a plane
// over many lines and pixels, and a straight line through whole-pixel crossings locates it to a
// fraction of one (the slanted-edge principle).
#pragma once
#include <cstdint>
#include <vector>

#include "core/calibration_objects.h"
#include "core/camera_model.h"
#include "core/fan_beam.h"

namespace rangex {

// Laser heights per line on a lateral grid (NaN where no camera saw the surface).
struct LaserProfiles {
  double x0_mm = -100, pitch_mm = 0.5;
  int n = 401;
  int64_t lines = 0;
  std::vector<float> h;  // lines x n
};

// Both cameras' stripe rows (lines x width, NaN where none) on the plane y = 0, binned
// onto the lateral grid (the mean of what falls in a bin).
LaserProfiles laser_profiles(const float* rows0, const float* rows1, int64_t lines, int width,
                             const CameraModel& cam0, const CameraModel& cam1);

struct WallLine {
  double a = 0, b = 0;
  bool ok = false;
  double at(double t) const { return a + b * t; }
};

struct BlockWalls {
  double height_mm = 0;              // measured by the laser (the drawing's is in the BlockSet)
  double xl_mm = 0, xh_mm = 0;       // lateral extent of the top in the laser's middle line
  WallLine laser_lead, laser_trail;  // laser line of the crossing as a function of x (mm)
  WallLine xray_lead, xray_trail;    // X-ray line of the crossing (at mid-height) of x
  WallLine xray_low, xray_high;      // side walls: x (mm, at mid-height) of the X-ray line
  int64_t laser_side_first = 0, laser_side_last = -1;  // lines clear of the leading and
  int64_t xray_side_first = 0, xray_side_last = -1;    // trailing walls, in each plane
};

// Throws Error naming the block when a block is not seen by both planes, the blocks found
// do not match the set's count, or a wall cannot be located.
std::vector<BlockWalls> find_block_walls(const LaserProfiles& laser, const uint16_t* xray,
                                         int64_t lines, const FanBeam& beam,
                                         const BlockSet& blocks);

// One camera's view of a block's top in one line: where the top ends on each side (the
// outermost column on the top; NaN where the side is hidden or off the image) and the
// top's row there.
struct TopEdge {
  int64_t line = 0;
  int side = 0;         // 0: the block's low-x side, 1: its high-x side
  double u = 0, v = 0;  // the outermost top column and its row
  int outward = 1;      // +1: the block's outside lies at larger u
};
struct TopView {
  std::vector<TopEdge> edges;
  std::vector<std::pair<double, double>> top;  // (u, v) of points well inside the top
};
TopView camera_top_view(const float* rows, int width, const CameraModel& cam,
                        const BlockWalls& block);

// Robust straight line t -> y: least squares, refitted twice without the points farther
// than `reject` (then reject / 2) from the line; not ok with fewer than 6 points.
WallLine robust_line(const std::vector<double>& t, const std::vector<double>& y, double reject);

}  // namespace rangex
