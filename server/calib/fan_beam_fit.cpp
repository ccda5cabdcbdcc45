#include "calib/fan_beam_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "calib/block_covariance.h"
#include "core/error.h"

namespace rangex {

namespace {

// p: source_x, source_z, first_pixel_x, pitch, detector_z, tilt (rad).
template <typename T>
T model_pixel(const T* p, double x, double z) {
  // Ray S + l (P - S) against detector line D0 + s (cos t, sin t).
  const T dx = T(x) - p[0], dz = T(z) - p[1];
  const T ex = cos(p[5]), ez = sin(p[5]);
  const T rx = p[2] - p[0], rz = p[4] - p[1];
  const T det = -dx * ez + ex * dz;
  const T s = (dx * rz - dz * rx) / det;
  return s / p[3];
}

struct PinCost {
  double x, z, u;
  template <typename T>
  bool operator()(const T* p, T* r) const {
    r[0] = model_pixel(p, x, z) - T(u);
    return true;
  }
};

struct OffsetPinCost {
  double x, z, u;
  template <typename T>
  bool operator()(const T* p, const T* offset, T* r) const {
    const T dx = T(x) + offset[0] - p[0], dz = T(z) - p[1];
    const T ex = cos(p[5]), ez = sin(p[5]);
    const T rx = p[2] - p[0], rz = p[4] - p[1];
    const T s = (dx * rz - dz * rx) / (-dx * ez + ex * dz);
    r[0] = s / p[3] - T(u);
    return true;
  }
};

// Gauge of the row offsets: sum(offset) = 0 and sum(offset * (h - mean h)) = 0, enforced
// with a weight that makes them exact to well below the data's precision.
struct OffsetGauge {
  std::vector<double> dh;  // h - mean h per row
  template <typename T>
  bool operator()(T const* const* off, T* r) const {
    r[0] = T(0), r[1] = T(0);
    for (size_t i = 0; i < dh.size(); ++i) {
      r[0] += off[i][0];
      r[1] += off[i][0] * T(dh[i] / 10);
    }
    r[0] *= T(1e4), r[1] *= T(1e4);
    return true;
  }
};

}  // namespace

double fan_beam_pixel(const FanBeam& fb, double x, double z) {
  const double p[6] = {fb.source_x_mm, fb.source_z_mm,   fb.first_pixel_x_mm,
                       fb.pitch_mm,    fb.detector_z_mm, fb.tilt_deg * M_PI / 180};
  const double u = model_pixel(p, x, z);
  return std::isfinite(u) ? u : std::nan("");
}

FanBeamFit fit_fan_beam(const std::vector<PinObservation>& pins, const FanBeamSolveOptions& opt) {
  if (pins.size() < 6) fail("too few pins: ", pins.size(), " (the fan beam needs at least 6)");
  std::set<double> heights;
  for (const PinObservation& o : pins) {
    if (!std::isfinite(o.x_mm) || !std::isfinite(o.z_mm) || !std::isfinite(o.pixel))
      fail("pin ", o.name, ": a value is not a number");
    if (o.z_mm <= opt.start.detector_z_mm || o.z_mm >= opt.start.source_z_mm)
      fail("pin ", o.name, ": height ", o.z_mm, " mm is not between the detector (",
           opt.start.detector_z_mm, " mm) and the source (", opt.start.source_z_mm, " mm)");
    if (o.pixel < -0.5 * opt.start.pixels || o.pixel > 1.5 * opt.start.pixels)
      fail("pin ", o.name, ": detector position ", o.pixel, " is far outside the ",
           opt.start.pixels, "-pixel detector");
    heights.insert(std::round(o.z_mm * 100) / 100);
  }
  if (heights.size() < 2)
    fail(
        "all pins stand at one height: the source height is undetermined (use pins at two "
        "or more heights)");
  double p[6] = {opt.start.source_x_mm, opt.start.source_z_mm,   opt.start.first_pixel_x_mm,
                 opt.start.pitch_mm,    opt.start.detector_z_mm, opt.start.tilt_deg * M_PI / 180};
  ceres::Problem problem;
  const std::vector<double> rows(heights.begin(), heights.end());
  std::vector<double> offset(rows.size(), 0.0);
  auto row_of = [&](double z) {
    return size_t(std::lower_bound(rows.begin(), rows.end(), std::round(z * 100) / 100) -
                  rows.begin());
  };
  const bool offsets = opt.row_offsets && rows.size() >= 3;
  for (const PinObservation& o : pins) {
    ceres::LossFunction* loss = opt.huber_px > 0 ? new ceres::HuberLoss(opt.huber_px) : nullptr;
    if (offsets)
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<OffsetPinCost, 1, 6, 1>(
                                   new OffsetPinCost{o.x_mm, o.z_mm, o.pixel}),
                               loss, p, &offset[row_of(o.z_mm)]);
    else
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<PinCost, 1, 6>(new PinCost{o.x_mm, o.z_mm, o.pixel}),
          loss, p);
  }
  if (offsets) {
    double mean = 0;
    for (double h : rows) mean += h / double(rows.size());
    auto* gauge = new OffsetGauge;
    for (double h : rows) gauge->dh.push_back(h - mean);
    auto* g = new ceres::DynamicAutoDiffCostFunction<OffsetGauge>(gauge);
    std::vector<double*> blocks;
    for (size_t i = 0; i < rows.size(); ++i) {
      g->AddParameterBlock(1);
      blocks.push_back(&offset[i]);
    }
    g->SetNumResiduals(2);
    problem.AddResidualBlock(g, nullptr, blocks);
  }
  std::vector<int> held = {opt.fit_pitch ? 4 : 3};
  if (!opt.fit_tilt) held.push_back(5);
  problem.SetManifold(p, new ceres::SubsetManifold(6, held));
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 200;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &problem, &sum);
  if (!sum.IsSolutionUsable()) fail("the fan-beam fit failed: ", sum.message);
  FanBeamFit fit;
  fit.converged = sum.termination_type == ceres::CONVERGENCE;
  fit.beam = opt.start;
  fit.beam.source_x_mm = p[0];
  fit.beam.source_z_mm = p[1];
  fit.beam.first_pixel_x_mm = p[2];
  fit.beam.pitch_mm = p[3];
  fit.beam.detector_z_mm = p[4];
  fit.beam.tilt_deg = p[5] * 180 / M_PI;
  double ss = 0;
  if (offsets)
    for (size_t i = 0; i < rows.size(); ++i) fit.row_offsets_mm.push_back({rows[i], offset[i]});
  for (const PinObservation& o : pins) {
    const double r =
        o.pixel - model_pixel(p, o.x_mm + (offsets ? offset[row_of(o.z_mm)] : 0.0), o.z_mm);
    fit.residual_px.push_back(r);
    ss += r * r;
    if (std::abs(r) > fit.worst_px) fit.worst_px = std::abs(r), fit.worst_pin = o.name;
  }
  fit.rms_px = std::sqrt(ss / double(pins.size()));
  fit.rms_mm = fit.rms_px * p[3];
  fit.worst_mm = fit.worst_px * p[3];
  const int free_params = 6 - int(held.size()) + (offsets ? int(rows.size()) - 2 : 0);
  const double sigma2 = ss / std::max(1.0, double(pins.size()) - free_params);
  const std::vector<double> sds = block_stddev(problem, p, 6, sigma2);
  const char* names[6] = {"source_x_mm", "source_z_mm",   "first_pixel_x_mm",
                          "pitch_mm",    "detector_z_mm", "tilt_deg"};
  for (int i = 0; i < 6; ++i) {
    const bool is_held = std::find(held.begin(), held.end(), i) != held.end();
    double sd = !sds.empty() && !is_held ? sds[i] : 0;
    double v = p[i];
    if (i == 5) v *= 180 / M_PI, sd *= 180 / M_PI;
    fit.estimates.push_back({names[i], v, sd, i == 5 ? "deg" : "mm"});
  }
  return fit;
}

SolveReport FanBeamFit::report(const std::string& subject) const {
  SolveReport r;
  r.solver = "xray";
  r.subject = subject;
  r.parameters = estimates;
  r.figures = {{"pins", double(residual_px.size())},
               {"rms_px", rms_px},
               {"worst_px", worst_px},
               {"rms_mm", rms_mm},
               {"worst_mm", worst_mm}};
  for (const auto& [h, o] : row_offsets_mm)
    r.parameters.push_back({"row_offset_z" + std::to_string(int(std::lround(h))), o, 0, "mm"});
  if (worst_px > 0) r.warnings.push_back("worst pin: " + worst_pin);
  if (!converged) {
    r.passed = false;
    r.failures.push_back("the fan-beam fit did not converge");
  }
  return r;
}

}  // namespace rangex
