// Camera intrinsics and lens distortion from views of a planar target (Laser Range Imaging
// §6.3.2.2): Zhang's closed form, then all intrinsics (fx, fy, cx, cy, skew), distortion (k1, k2,
// p1, p2, k3) and every view's pose refined jointly by Levenberg-Marquardt (Ceres) with a Huber
// loss, the standard deviation of every parameter from the fit's covariance, and a map of
// how far a projected point may move over the sensor given that covariance.
#pragma once
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "calib/solve_report.h"
#include "calib/zhang_init.h"
#include "core/camera_model.h"

namespace rangex {

struct TargetView {
  std::string name;  // image file, for messages
  PlanarView points;
};

struct CameraSolveOptions {
  // Parameters held at their start value, in CameraFit::kNames order (fx fy cx cy skew k1
  // k2 p1 p2 k3); a held distortion term stays 0, a held skew 0, a held cx/cy at the
  // closed form's value unless `start` gives one.
  std::array<bool, 10> fixed{};
  const Intrinsics* start = nullptr;  // nominal intrinsics for held cx, cy (data sheet)
  double huber_px = 1.0;  // residuals beyond this count linearly (a mis-detected corner)
  int max_iterations = 200;
  int min_views = 5;
  int map_step_px = 16;  // uncertainty map node spacing
  int coverage_cells_x = 8, coverage_cells_y = 4;
  std::function<void(const std::string&)> progress;  // one line per iteration
};

struct UncertaintyMap {
  int step = 16, cols = 0, rows = 0;  // node (i, j) at pixel (i * step, j * step)
  std::vector<float> px;              // 1-sigma projection shift, worst direction
  double median = 0, worst = 0;
  double working_distance_mm = 0;  // depth of the projected points (median view depth)
};

struct CameraFit {
  Intrinsics intrinsics;
  Distortion distortion;
  Intrinsics zhang;  // the closed-form start
  static constexpr std::array<const char*, 10> kNames = {"fx", "fy", "cx", "cy", "skew",
                                                         "k1", "k2", "p1", "p2", "k3"};
  std::array<double, 10> value{}, stddev{};
  struct View {
    std::string name;
    Mat3 R;
    Vec3 t;
    double rms_px = 0, worst_px = 0;
  };
  std::vector<View> views;
  // Per corner: the observed pixel and its residual (observed - model).
  std::vector<Vec2> corner_px, residual_px;
  double rms_px = 0, worst_px = 0, rms_mm = 0, worst_mm = 0;
  int iterations = 0;
  bool converged = false;
  UncertaintyMap map;
  double coverage = 0;  // fraction of sensor cells holding at least one corner
  std::vector<std::string> warnings;

  SolveReport report(const std::string& subject) const;
};

// Throws Error naming the view for too few views or corners, and for a degenerate pose set.
CameraFit calibrate_camera(const std::vector<TargetView>& views, int width, int height,
                           const CameraSolveOptions& opt = {});

// The 10 parameters in CameraFit's order and back.
std::array<double, 10> camera_parameters(const Intrinsics& k, const Distortion& d);

}  // namespace rangex
