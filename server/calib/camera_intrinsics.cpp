#include "calib/camera_intrinsics.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace rangex {

namespace {

// u = fx * (xd + skew * yd) + cx, v = fy * yd + cy with OpenCV's distortion: the model of
// core/camera_model.h written once for Ceres' jets.
template <typename T>
void project(const T* in, const T* di, const T* c, T* uv) {
  const T x = c[0] / c[2], y = c[1] / c[2];
  const T r2 = x * x + y * y;
  const T radial = T(1) + r2 * (di[0] + r2 * (di[1] + r2 * di[4]));
  const T xd = x * radial + T(2) * di[2] * x * y + di[3] * (r2 + T(2) * x * x);
  const T yd = y * radial + di[2] * (r2 + T(2) * y * y) + T(2) * di[3] * x * y;
  uv[0] = in[0] * (xd + in[4] * yd) + in[2];
  uv[1] = in[1] * yd + in[3];
}

struct CornerCost {
  double X, Y, Z, u, v;
  template <typename T>
  bool operator()(const T* in, const T* di, const T* rot, const T* tr, T* res) const {
    const T p[3] = {T(X), T(Y), T(Z)};
    T c[3];
    ceres::AngleAxisRotatePoint(rot, p, c);
    c[0] += tr[0], c[1] += tr[1], c[2] += tr[2];
    T uv[2];
    project(in, di, c, uv);
    res[0] = uv[0] - u;
    res[1] = uv[1] - v;
    return true;
  }
};

struct Progress : ceres::IterationCallback {
  const std::function<void(const std::string&)>& out;
  explicit Progress(const std::function<void(const std::string&)>& o) : out(o) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    char b[160];
    std::snprintf(b, sizeof b, "  iteration %3d  cost %.6g  step %.3g", s.iteration, s.cost,
                  s.step_norm);
    out(b);
    return ceres::SOLVER_CONTINUE;
  }
};

Mat3 from_angle_axis(const double* aa) {
  double R[9];
  ceres::AngleAxisToRotationMatrix(aa, ceres::RowMajorAdapter3x3(R));
  Mat3 m;
  for (int i = 0; i < 9; ++i) m.m[i] = R[i];
  return m;
}

// Zhang's closed-form start from the views, once every corner is checked to lie on the
// sensor.
ZhangStart zhang_start(const std::vector<TargetView>& views, int width, int height) {
  std::vector<PlanarView> planar;
  for (const TargetView& v : views) {
    for (const Vec2& p : v.points.pixels)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || p.x < -0.5 || p.y < -0.5 ||
          p.x > width - 0.5 || p.y > height - 0.5)
        fail("target view ", v.name, ": corner (", p.x, ", ", p.y, ") lies outside the ", width,
             "x", height, " sensor");
    planar.push_back(v.points);
  }
  try {
    return zhang_initialise(planar);
  } catch (const Error& e) {
    fail(e.what());
  }
}

// The parameters held fixed (intrinsics, then distortion) stay at their start.
void hold_fixed(ceres::Problem& problem, double* in, double* di, const std::array<bool, 10>& fx) {
  std::vector<int> held_in, held_di;
  for (int i = 0; i < 5; ++i) {
    if (fx[i]) held_in.push_back(i);
    if (fx[5 + i]) held_di.push_back(i);
  }
  if (held_in.size() == 5)
    problem.SetParameterBlockConstant(in);
  else if (!held_in.empty())
    problem.SetManifold(in, new ceres::SubsetManifold(5, held_in));
  if (held_di.size() == 5)
    problem.SetParameterBlockConstant(di);
  else if (!held_di.empty())
    problem.SetManifold(di, new ceres::SubsetManifold(5, held_di));
}

// Residuals in px, and in mm on the target (a pixel spans depth / f there), per view and in
// all. Appends each corner's depth; returns the residuals' sum of squares (px^2).
double residual_figures(CameraFit& fit, const std::vector<TargetView>& views,
                        const std::vector<std::array<double, 6>>& pose, const double* in,
                        const double* di, std::vector<double>& depth) {
  double ss = 0, ss_mm = 0;
  for (size_t k = 0; k < views.size(); ++k) {
    CameraFit::View fv;
    fv.name = views[k].name;
    fv.R = from_angle_axis(pose[k].data());
    fv.t = {pose[k][3], pose[k][4], pose[k][5]};
    double vs = 0;
    const PlanarView& v = views[k].points;
    for (size_t i = 0; i < v.board.size(); ++i) {
      const Vec3 c = fv.R * v.board[i] + fv.t;
      double cc[3] = {c.x, c.y, c.z}, uv[2];
      project(in, di, cc, uv);
      const Vec2 r{v.pixels[i].x - uv[0], v.pixels[i].y - uv[1]};
      const double e2 = r.x * r.x + r.y * r.y;
      const double mx = r.x * c.z / in[0], my = r.y * c.z / in[1];
      fit.corner_px.push_back(v.pixels[i]);
      fit.residual_px.push_back(r);
      vs += e2;
      ss += e2;
      ss_mm += mx * mx + my * my;
      fv.worst_px = std::max(fv.worst_px, std::sqrt(e2));
      fit.worst_mm = std::max(fit.worst_mm, std::hypot(mx, my));
      depth.push_back(c.z);
    }
    fv.rms_px = std::sqrt(vs / double(v.board.size()));
    fit.worst_px = std::max(fit.worst_px, fv.worst_px);
    fit.views.push_back(fv);
  }
  const double corners = double(fit.corner_px.size());
  fit.rms_px = std::sqrt(ss / corners);
  fit.rms_mm = std::sqrt(ss_mm / corners);
  return ss;
}

// Covariance of the 10 lens parameters (intrinsics, then distortion), scaled by `sigma2`,
// the residual variance per coordinate (Ceres gives (J^T J)^-1 for unit-variance
// residuals). Zero, with a warning, where the fit is rank-deficient.
Eigen::Matrix<double, 10, 10> lens_covariance(ceres::Problem& problem, const double* in,
                                              const double* di, double sigma2,
                                              std::vector<std::string>& warnings) {
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{in, in}, {in, di}, {di, di}};
  Eigen::Matrix<double, 10, 10> C = Eigen::Matrix<double, 10, 10>::Zero();
  if (cov.Compute(blocks, &problem)) {
    double a[25], b[25], c[25];
    cov.GetCovarianceBlock(in, in, a);
    cov.GetCovarianceBlock(in, di, b);
    cov.GetCovarianceBlock(di, di, c);
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < 5; ++j) {
        C(i, j) = a[i * 5 + j];
        C(i, 5 + j) = b[i * 5 + j];
        C(5 + j, i) = b[i * 5 + j];
        C(5 + i, 5 + j) = c[i * 5 + j];
      }
    C *= sigma2;
  } else {
    warnings.push_back("the covariance could not be computed (rank-deficient fit)");
  }
  return C;
}

// Uncertainty map: a point on the ray through each node at the working distance (the
// corners' median depth), projected with parameters moved along the covariance (first
// order).
void uncertainty_map(CameraFit& fit, const Eigen::Matrix<double, 10, 10>& C,
                     std::vector<double>& depth, int width, int height, int step) {
  std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
  UncertaintyMap& m = fit.map;
  m.step = step;
  m.working_distance_mm = depth[depth.size() / 2];
  m.cols = (width - 1) / m.step + 1;
  m.rows = (height - 1) / m.step + 1;
  const CameraModel model(fit.intrinsics, fit.distortion, Mat3{}, Vec3{}, width, height);
  for (int j = 0; j < m.rows; ++j)
    for (int i = 0; i < m.cols; ++i) {
      const Vec2 ideal =
          model.undistort(model.pixel_to_normalized({double(i * m.step), double(j * m.step)}));
      const double P[3] = {ideal.x * m.working_distance_mm, ideal.y * m.working_distance_mm,
                           m.working_distance_mm};
      Eigen::Matrix<double, 2, 10> J;
      for (int p = 0; p < 10; ++p) {
        double a[10];
        std::copy(fit.value.begin(), fit.value.end(), a);
        const double h = 1e-6 * std::max(1.0, std::abs(a[p]));
        double up[2], dn[2];
        a[p] += h;
        project(a, a + 5, P, up);
        a[p] -= 2 * h;
        project(a, a + 5, P, dn);
        J(0, p) = (up[0] - dn[0]) / (2 * h);
        J(1, p) = (up[1] - dn[1]) / (2 * h);
      }
      const Eigen::Matrix2d S = J * C * J.transpose();
      const double worst = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(S).eigenvalues()(1);
      m.px.push_back(float(std::sqrt(std::max(0.0, worst))));
    }
  std::vector<float> sorted = m.px;
  std::sort(sorted.begin(), sorted.end());
  m.median = sorted[sorted.size() / 2];
  m.worst = sorted.back();
}

// Coverage: sensor cells (cx x cy over the image) without a corner are extrapolated, not
// measured; a warning names them.
void sensor_coverage(CameraFit& fit, int width, int height, int cx, int cy) {
  std::vector<int> seen(size_t(cx) * cy, 0);
  for (const Vec2& p : fit.corner_px) {
    const int i = std::clamp(int(p.x * cx / width), 0, cx - 1);
    const int j = std::clamp(int(p.y * cy / height), 0, cy - 1);
    seen[size_t(j) * cx + i] = 1;
  }
  int covered = 0;
  std::string empty;
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i) {
      if (seen[size_t(j) * cx + i]) {
        ++covered;
        continue;
      }
      empty += join(empty.empty() ? "" : ", ", "[", i * width / cx, "..", (i + 1) * width / cx,
                    ") x [", j * height / cy, "..", (j + 1) * height / cy, ")");
    }
  fit.coverage = double(covered) / double(cx * cy);
  if (covered < cx * cy)
    fit.warnings.push_back(join("the target poses leave ", cx * cy - covered, " of ", cx * cy,
                                " sensor cells without a corner (px ", empty,
                                "): the lens model is extrapolated there; add views that "
                                "put the target into those parts of the image"));
}

}  // namespace

std::array<double, 10> camera_parameters(const Intrinsics& k, const Distortion& d) {
  return {k.fx, k.fy, k.cx, k.cy, k.skew, d.k1, d.k2, d.p1, d.p2, d.k3};
}

CameraFit calibrate_camera(const std::vector<TargetView>& views, int width, int height,
                           const CameraSolveOptions& opt) {
  if (int(views.size()) < opt.min_views)
    fail("too few target views: ", views.size(), " usable, at least ", opt.min_views,
         " needed (tilted differently, spread over the sensor)");
  const ZhangStart z = zhang_start(views, width, height);
  CameraFit fit;
  fit.zhang = z.intrinsics;
  const auto& fx = opt.fixed;
  double in[5] = {z.intrinsics.fx, z.intrinsics.fy, z.intrinsics.cx, z.intrinsics.cy,
                  fx[4] ? 0.0 : z.intrinsics.skew};
  if (opt.start) {
    if (fx[2]) in[2] = opt.start->cx;
    if (fx[3]) in[3] = opt.start->cy;
  }
  double di[5] = {0, 0, 0, 0, 0};
  std::vector<std::array<double, 6>> pose(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    double R[9];
    for (int i = 0; i < 9; ++i) R[i] = z.R[k].m[i];
    ceres::RotationMatrixToAngleAxis(ceres::RowMajorAdapter3x3<const double>(R), pose[k].data());
    pose[k][3] = z.t[k].x, pose[k][4] = z.t[k].y, pose[k][5] = z.t[k].z;
  }

  ceres::Problem problem;
  size_t corners = 0;
  for (size_t k = 0; k < views.size(); ++k) {
    const PlanarView& v = views[k].points;
    for (size_t i = 0; i < v.board.size(); ++i, ++corners) {
      auto* cost = new ceres::AutoDiffCostFunction<CornerCost, 2, 5, 5, 3, 3>(
          new CornerCost{v.board[i].x, v.board[i].y, v.board[i].z, v.pixels[i].x, v.pixels[i].y});
      problem.AddResidualBlock(cost, new ceres::HuberLoss(opt.huber_px), in, di, pose[k].data(),
                               pose[k].data() + 3);
    }
  }
  hold_fixed(problem, in, di, fx);

  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = opt.max_iterations;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  Progress progress(opt.progress);
  if (opt.progress) {
    so.callbacks.push_back(&progress);
    so.update_state_every_iteration = false;
  }
  ceres::Solver::Summary sum;
  ceres::Solve(so, &problem, &sum);
  fit.iterations = int(sum.iterations.size());
  fit.converged = sum.termination_type == ceres::CONVERGENCE;
  if (!sum.IsSolutionUsable()) fail("camera calibration did not converge: ", sum.message);

  fit.intrinsics = {in[0], in[1], in[2], in[3], in[4]};
  fit.distortion = {di[0], di[1], di[2], di[3], di[4]};
  fit.value = camera_parameters(fit.intrinsics, fit.distortion);

  std::vector<double> depth;
  const double ss = residual_figures(fit, views, pose, in, di, depth);

  // The lens parameters' covariance, scaled by the residual variance per coordinate.
  const int free_params = 10 - int(std::count(fx.begin(), fx.end(), true)) + 6 * int(views.size());
  const double dof = std::max(1.0, 2.0 * double(corners) - free_params);
  const Eigen::Matrix<double, 10, 10> C = lens_covariance(problem, in, di, ss / dof, fit.warnings);
  for (int i = 0; i < 10; ++i) fit.stddev[i] = std::sqrt(std::max(0.0, C(i, i)));

  uncertainty_map(fit, C, depth, width, height, opt.map_step_px);
  sensor_coverage(fit, width, height, opt.coverage_cells_x, opt.coverage_cells_y);
  const UncertaintyMap& m = fit.map;
  if (m.worst > 4 * m.median)
    fit.warnings.push_back(join("projection uncertainty reaches ", m.worst, " px (median ",
                                m.median, " px): parts of the sensor are poorly constrained"));
  if (!fit.converged)
    fit.warnings.push_back(join("the refinement stopped without converging: ", sum.message));
  return fit;
}

SolveReport CameraFit::report(const std::string& subject) const {
  SolveReport r;
  r.solver = "camera";
  r.subject = subject;
  const char* units[10] = {"px", "px", "px", "px", "", "", "", "", "", ""};
  for (int i = 0; i < 10; ++i) r.parameters.push_back({kNames[i], value[i], stddev[i], units[i]});
  r.figures = {{"views", double(views.size())},
               {"corners", double(corner_px.size())},
               {"rms_px", rms_px},
               {"worst_px", worst_px},
               {"rms_mm", rms_mm},
               {"worst_mm", worst_mm},
               {"iterations", double(iterations)},
               {"sensor_coverage", coverage},
               {"uncertainty_median_px", map.median},
               {"uncertainty_worst_px", map.worst},
               {"working_distance_mm", map.working_distance_mm}};
  r.warnings = warnings;
  if (!converged) {
    r.passed = false;
    r.failures.push_back("the refinement did not converge");
  }
  return r;
}

}  // namespace rangex
