#include "calib/dual_energy_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/error.h"

namespace rangex {

namespace {

// The two log attenuations of a step.
void logs(const WedgeScan& scan, const WedgeStep& s, double* x, double* y) {
  *x = std::log(scan.open_low / s.low);
  *y = std::log(scan.open_high / s.high);
}

}  // namespace

std::array<double, 2> basis_lengths(Material m, const LayerSpectra& s, const DualEnergyParams& p) {
  // Bone comes in millimetres, meat in centimetres.
  const double top = m == Material::kBone ? 6 : 50;
  double sa = 0, sb = 0, stt = 0;
  for (int k = 1; k <= 10; ++k) {
    const double t = top * k / 10;
    double x, y, a, b, j[4];
    layer_log_attenuations(
        s, [&](double e) { return attenuation_per_mm(m, e) * t; }, &x, &y);
    if (!dual_energy_invert(p, x, y, &a, &b, j))
      fail("dual energy: ", t, " mm of ", material_name(m), " is outside the calibration");
    sa += a * t, sb += b * t, stt += t * t;
  }
  return {sa / stt, sb / stt};
}

DualEnergyFit fit_dual_energy(const WedgeScan& scan, const SandwichDetector& nominal,
                              double laser_sigma_mm) {
  if (!(scan.open_low > 0 && scan.open_high > 0))
    fail("dual-energy wedge scan: no open beam (the bare belt's readings must be > 0)");
  if (scan.steps.size() < 2 * DE_TERMS)
    fail("dual-energy wedge scan: ", scan.steps.size(), " steps; the fit needs at least ",
         2 * DE_TERMS);
  if (!(laser_sigma_mm >= 0)) fail("dual energy: the laser's sigma must be >= 0 mm");
  const int n = int(scan.steps.size());
  // Each layer's log attenuation from the steps' known lengths, weighted by the precision
  // of the step's mean (var(ln mean) = var / (samples x mean^2)).
  Eigen::MatrixXd X(n, DE_TERMS);
  Eigen::VectorXd lx(n), ly(n), wx(n), wy(n);
  for (int i = 0; i < n; ++i) {
    const WedgeStep& s = scan.steps[size_t(i)];
    if (!(s.low > 0 && s.high > 0 && s.low < scan.open_low * 1.5 && s.high < scan.open_high * 1.5))
      fail("dual-energy wedge step ", i, " (", s.a150_mm, " mm A-150, ", s.al_mm,
           " mm Al): readings ", s.low, " / ", s.high, " DN are not a transmission");
    logs(scan, s, &lx(i), &ly(i));
    double t[DE_TERMS];
    dual_energy_terms(s.a150_mm / DE_A_MM, s.al_mm / DE_B_MM, t);
    for (int j = 0; j < DE_TERMS; ++j) X(i, j) = t[j];
    const double m = std::max(1, s.samples);
    wx(i) = std::sqrt(m * s.low * s.low / std::max(s.var_low, 1e-9));
    wy(i) = std::sqrt(m * s.high * s.high / std::max(s.var_high, 1e-9));
  }
  const auto qx = (wx.asDiagonal() * X).colPivHouseholderQr();
  const auto qy = (wy.asDiagonal() * X).colPivHouseholderQr();
  // Steps that do not vary both thicknesses cannot fix every term: refused, not guessed.
  if (qx.rank() < DE_TERMS || qy.rank() < DE_TERMS)
    fail("dual-energy wedge scan: its steps fix ", std::min(qx.rank(), qy.rank()), " of the ",
         DE_TERMS, " terms; the steps must cross both thicknesses over their ranges");
  const Eigen::VectorXd cl = qx.solve(wx.asDiagonal() * lx);
  const Eigen::VectorXd ch = qy.solve(wy.asDiagonal() * ly);
  DualEnergyFit f;
  for (int j = 0; j < DE_TERMS; ++j) f.params.low[j] = cl(j), f.params.high[j] = ch(j);
  // The calibration's own error: each step's reading taken back to its lengths.
  f.steps = evaluate_wedge(f.params, scan);
  double sa = 0, sb = 0;
  for (const DualEnergyFit::Step& s : f.steps) {
    if (!std::isfinite(s.a_fit) || !std::isfinite(s.b_fit))
      fail("dual-energy calibration: the fit cannot be inverted at the step of ", s.a150_mm,
           " mm A-150 and ", s.al_mm, " mm Al");
    sa += (s.a_fit - s.a150_mm) * (s.a_fit - s.a150_mm);
    sb += (s.b_fit - s.al_mm) * (s.b_fit - s.al_mm);
    if (s.a150_mm >= 1)
      f.a_worst_rel = std::max(f.a_worst_rel, std::abs(s.a_fit - s.a150_mm) / s.a150_mm);
    if (s.al_mm >= 1)
      f.b_worst_rel = std::max(f.b_worst_rel, std::abs(s.b_fit - s.al_mm) / s.al_mm);
  }
  f.a_rms = std::sqrt(sa / n);
  f.b_rms = std::sqrt(sb / n);
  f.params.var_a = f.a_rms * f.a_rms;
  f.params.var_b = f.b_rms * f.b_rms;

  // Noise: var = gain x mean + var_e per layer, least squares over the steps.
  auto noise = [&](bool low, double* gain, double* var_e) {
    Eigen::MatrixXd M(n, 2);
    Eigen::VectorXd v(n);
    for (int i = 0; i < n; ++i) {
      const WedgeStep& s = scan.steps[size_t(i)];
      M(i, 0) = low ? s.low : s.high;
      M(i, 1) = 1;
      v(i) = low ? s.var_low : s.var_high;
    }
    const Eigen::Vector2d g = M.colPivHouseholderQr().solve(v);
    if (!(g(0) > 0))
      fail("dual-energy wedge scan: the ", low ? "low" : "high",
           " layer's variance does not rise with its signal (gain ", g(0), ")");
    *gain = g(0);
    *var_e = std::max(0.0, g(1));
  };
  noise(true, &f.params.gain_low, &f.params.var_e_low);
  noise(false, &f.params.gain_high, &f.params.var_e_high);
  f.params.var_t = laser_sigma_mm * laser_sigma_mm;

  // The materials in the basis, and the inverse the pixels use.
  const LayerSpectra spectra = layer_spectra(nominal);
  const Material mats[3] = {Material::kLean, Material::kFat, Material::kBone};
  Eigen::Matrix3d M;
  for (int m = 0; m < 3; ++m) {
    const auto [a, b] = basis_lengths(mats[m], spectra, f.params);
    f.params.basis[2 * m] = M(0, m) = a;
    f.params.basis[2 * m + 1] = M(1, m) = b;
    M(2, m) = 1;
  }
  if (std::abs(M.determinant()) < 1e-9)
    fail("dual energy: lean, fat and bone are not separable in this detector's basis");
  const Eigen::Matrix3d inv = M.inverse();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) f.params.minv[3 * r + c] = inv(r, c);
  return f;
}

std::vector<DualEnergyFit::Step> evaluate_wedge(const DualEnergyParams& p, const WedgeScan& scan) {
  std::vector<DualEnergyFit::Step> out;
  for (const WedgeStep& s : scan.steps) {
    double x, y, a, b, j[4];
    logs(scan, s, &x, &y);
    if (!dual_energy_invert(p, x, y, &a, &b, j)) a = b = std::nan("");
    out.push_back({s.a150_mm, s.al_mm, a, b});
  }
  return out;
}

std::string dual_energy_report(const DualEnergyFit& f) {
  std::ostringstream os;
  os << "dual-energy calibration: " << f.steps.size()
     << " wedge steps; each layer's log attenuation a polynomial of degree " << DE_DEGREE
     << " in the basis lengths\n"
     << "  A-150 recovered: rms " << f.a_rms << " mm, worst " << 100 * f.a_worst_rel
     << " % of a step\n"
     << "  aluminium recovered: rms " << f.b_rms << " mm, worst " << 100 * f.b_worst_rel
     << " % of a step\n"
     << "  noise: low layer " << f.params.gain_low << " DN per DN + " << f.params.var_e_low
     << " DN^2, high layer " << f.params.gain_high << " + " << f.params.var_e_high << "\n";
  const char* names[3] = {"lean", "fat", "bone"};
  for (int m = 0; m < 3; ++m)
    os << "  " << names[m] << " per mm: " << f.params.basis[2 * m] << " mm A-150 + "
       << f.params.basis[2 * m + 1] << " mm Al\n";
  return os.str();
}

}  // namespace rangex
