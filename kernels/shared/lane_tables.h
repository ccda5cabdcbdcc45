// Per-lane tables as the kernels read them, written once for C++, OpenCL C and GLSL (std430
// buffers): only int, float and double members, each struct a multiple of 8 bytes, doubles
// first. Built on the host from a LaneConfig when lanes are set or a calibration activates
// (server/backends/lane_tables.cpp), uploaded once, read by every batch.
#ifndef RANGEX_LANE_TABLES_H
#define RANGEX_LANE_TABLES_H

#ifdef __cplusplus
namespace rangex::kernel {
#endif

// Stripe extraction settings of one (lane, camera): index lane * 2 + camera.
struct StripeSlotK {
  int method;  // StripeMethod, in its declaration order
  int min_peak;
  float threshold_rel;
  int max_width;
  float k1;
  float k2;
  float k2_offset;
  int pad0;
};

// One camera's rectification table: nu x nv nodes `step` pixels apart; node (i, j) has x at
// nodes[offset + j * nu + i] and z at nodes[offset + nu * nv + j * nu + i].
struct RectTableK {
  int step;
  int nu;
  int nv;
  int offset;
};

// One lane's fusion grid and fan beam (double, as the CPU reference computes them).
struct LaneGeomK {
  double grid_x0_mm;
  double grid_pitch_mm;
  double agree_tol_mm;
  double max_column_step_mm;
  double first_pixel_x_mm;  // detector pixel i sits at (first_pixel_x_mm + pitch_mm * i,
  double pitch_mm;          //  detector_z_mm + pitch_z_mm * i): a tilted detector rises
  double detector_z_mm;
  double source_x_mm;
  double source_z_mm;
  double pitch_z_mm;
  int grid_n;
  int pixels;
  int max_gap;  // samples: floor(max_gap_mm / grid_pitch_mm + 1e-9)
  int pad1;
};

// Fusion counts of one line, as FusionStats.
struct FusionCountK {
  int both;
  int single_cam;
  int conflict;
  int filled;
  int missing;
  int pad0;
};

#ifdef __cplusplus
static_assert(sizeof(StripeSlotK) == 32, "StripeSlotK must match the kernels' layout");
static_assert(sizeof(RectTableK) == 16, "RectTableK must match the kernels' layout");
static_assert(sizeof(LaneGeomK) == 96, "LaneGeomK must match the kernels' layout");
static_assert(sizeof(FusionCountK) == 24, "FusionCountK must match the kernels' layout");
}  // namespace rangex::kernel
#endif

#endif
