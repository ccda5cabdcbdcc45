#include "calib/registration_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "calib/staircase_fit.h"
#include "core/error.h"

namespace rangex {

namespace {

struct Run {
  int64_t a, b;  // first and last line
};

// Runs of lines where `on(line)` holds, at least `min_len` long.
template <typename F>
std::vector<Run> runs(int64_t lines, F on, int64_t min_len) {
  std::vector<Run> r;
  for (int64_t n = 0; n < lines;) {
    if (!on(n)) {
      ++n;
      continue;
    }
    int64_t e = n;
    while (e + 1 < lines && on(e + 1)) ++e;
    if (e - n + 1 >= min_len) r.push_back({n, e});
    n = e + 1;
  }
  return r;
}

// Sub-line position where v crosses `level` between lines n-1 and n, searching from
// `from` in direction `dir`; NaN when no bracketing pair of valid values is found.
template <typename V>
double crossing(V v, int64_t from, int dir, int64_t lines, double level, int64_t reach) {
  for (int64_t k = 0; k < reach; ++k) {
    const int64_t n = from + dir * k, m = n + dir;
    if (m < 0 || m >= lines) break;
    const double a = v(n), b = v(m);
    if (!std::isfinite(a) || !std::isfinite(b)) continue;
    if ((a - level) * (b - level) <= 0 && a != b) return double(n) + dir * (level - a) / (b - a);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

struct Line {
  double a = 0, b = 0;
  bool ok = false;
  double at(double x) const { return a + b * x; }
};

// Least-squares line through the finite points, refitted without those more than 1.5
// lines off (a column that saw a side wall or an occluded stripe).
Line robust_line(const std::vector<double>& x, const std::vector<double>& y) {
  Line l;
  std::vector<uint8_t> use(x.size());
  for (size_t i = 0; i < x.size(); ++i) use[i] = std::isfinite(y[i]);
  for (int pass = 0; pass < 3; ++pass) {
    double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t i = 0; i < x.size(); ++i)
      if (use[i]) n += 1, sx += x[i], sy += y[i], sxx += x[i] * x[i], sxy += x[i] * y[i];
    const double den = n * sxx - sx * sx;
    if (n < 6 || std::abs(den) < 1e-9) return Line{};
    l.b = (n * sxy - sx * sy) / den;
    l.a = (sy - l.b * sx) / n;
    l.ok = true;
    for (size_t i = 0; i < x.size(); ++i)
      use[i] = std::isfinite(y[i]) && std::abs(y[i] - l.at(x[i])) < (pass == 0 ? 3.0 : 1.5);
  }
  return l;
}

}  // namespace

LaserProfiles laser_profiles(const float* rows0, const float* rows1, int64_t lines, int width,
                             const CameraModel& cam0, const CameraModel& cam1) {
  LaserProfiles L;
  L.lines = lines;
  L.h.assign(size_t(lines) * L.n, std::numeric_limits<float>::quiet_NaN());
  std::vector<double> sum(L.n);
  std::vector<int> count(L.n);
  for (int64_t n = 0; n < lines; ++n) {
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (int cam = 0; cam < 2; ++cam) {
      const float* rows = cam == 0 ? rows0 : rows1;
      const CameraModel& c = cam == 0 ? cam0 : cam1;
      for (int u = 0; u < width; ++u) {
        const float v = rows[n * width + u];
        if (!std::isfinite(v)) continue;
        double x = 0;
        const double h = plane_height(c, u, v, &x);
        const int g = int(std::lround((x - L.x0_mm) / L.pitch_mm));
        if (!std::isfinite(h) || g < 0 || g >= L.n) continue;
        sum[g] += h, ++count[g];
      }
    }
    for (int g = 0; g < L.n; ++g)
      if (count[g]) L.h[n * L.n + g] = float(sum[g] / count[g]);
  }
  return L;
}

RegistrationFit fit_registration(const LaserProfiles& L, const uint16_t* xray, int64_t lines,
                                 const FanBeam& fb, double step, const BlockSet& set) {
  const int P = fb.pixels;
  if (L.lines != lines) fail("laser and X-ray scans differ in length: ", L.lines, " vs ", lines);
  // Blocks as the laser sees them: runs of lines with a flat top above 2 mm.
  auto laser_top = [&](int64_t n) {
    int c = 0;
    for (int k = 0; k < L.n; ++k) c += L.h[n * L.n + k] > 2;
    return c >= 4;
  };
  const auto lr = runs(lines, laser_top, 5);
  // X-ray: open beam by the median over the scan, attenuation per line and pixel.
  std::vector<double> open(P);
  std::vector<uint16_t> col(lines);
  for (int i = 0; i < P; ++i) {
    for (int64_t n = 0; n < lines; ++n) col[n] = xray[n * P + i];
    std::nth_element(col.begin(), col.begin() + lines / 2, col.end());
    open[i] = std::max<double>(1, col[lines / 2]);
  }
  auto att = [&](int64_t n, int i) {
    return std::log(open[i] / std::max(1.0, double(xray[n * P + i])));
  };
  auto xray_dark = [&](int64_t n) {
    int c = 0;
    for (int i = 0; i < P; ++i) c += att(n, i) > 0.04;
    return c >= 4;
  };
  const auto xr = runs(lines, xray_dark, 5);
  if (lr.size() != set.blocks.size() || xr.size() != set.blocks.size())
    fail("the registration scan shows ", lr.size(), " blocks under the laser and ", xr.size(),
         " in the X-ray; the block set has ", set.blocks.size(),
         " (a block missed a plane, or blocks touch)");
  std::vector<double> ox, oz, od;  // observations: x, z, delay (lines)
  struct Corner {
    double x, laser, xray, z;  // a wall's crossing line in each plane at x
  };
  std::vector<Corner> corners;
  RegistrationFit f;
  for (size_t k = 0; k < lr.size(); ++k) {
    const Run l = lr[k], x = xr[k];
    // Top height and lateral extent from the laser's middle lines.
    const int64_t mid = (l.a + l.b) / 2;
    std::vector<float> top;
    int kmin = L.n, kmax = -1;
    for (int g = 0; g < L.n; ++g) {
      const float h = L.h[mid * L.n + g];
      if (h > 2) top.push_back(h), kmin = std::min(kmin, g), kmax = std::max(kmax, g);
    }
    if (top.size() < 4) fail("block ", k, ": too narrow in the laser scan");
    std::nth_element(top.begin(), top.begin() + top.size() / 2, top.end());
    const double h = top[top.size() / 2];
    const double xl = L.x0_mm + L.pitch_mm * kmin, xh = L.x0_mm + L.pitch_mm * kmax;
    const double zm = 0.5 * h;
    const double reach = double(l.b - l.a) / 2 + 40;
    // Each wall's crossing line as a function of x, in each plane, for the block's inner
    // width (3 mm from its sides). The blocks stand askew, so a wall crosses a plane over
    // several lines across the belt: a straight line through the (whole-line) laser
    // crossings measures the wall to a fraction of a line.
    std::vector<double> lx, ll, lt, px, pl, pt;
    for (int g = 0; g < L.n; ++g) {
      const double xg = L.x0_mm + L.pitch_mm * g;
      if (xg < xl + 3 || xg > xh - 3) continue;
      auto lv = [&](int64_t n) { return double(L.h[n * L.n + g]); };
      lx.push_back(xg);
      ll.push_back(crossing(lv, mid, -1, lines, 0.5 * h, int64_t(reach)));
      lt.push_back(crossing(lv, mid, +1, lines, 0.5 * h, int64_t(reach)));
    }
    const int64_t xmid = (x.a + x.b) / 2;
    for (int i = 0; i < P; ++i) {
      const double xd = fb.pixel_x(i), zd = fb.pixel_z(i);
      const double xm = xd + (fb.source_x_mm - xd) * (zm - zd) / (fb.source_z_mm - zd);
      if (xm < xl + 3 || xm > xh - 3) continue;
      const double plateau = att(xmid, i);
      auto xv = [&](int64_t n) { return att(n, i); };
      px.push_back(xm);
      pl.push_back(crossing(xv, xmid, -1, lines, 0.5 * plateau, int64_t(reach)));
      pt.push_back(crossing(xv, xmid, +1, lines, 0.5 * plateau, int64_t(reach)));
    }
    for (int wall = 0; wall < 2; ++wall) {
      const Line a = robust_line(lx, wall ? lt : ll), b = robust_line(px, wall ? pt : pl);
      if (!a.ok || !b.ok) continue;
      for (double xs = xl + 3; xs <= xh - 3; xs += 2) {
        ox.push_back(xs), oz.push_back(zm), od.push_back(b.at(xs) - a.at(xs));
        corners.push_back({xs, a.at(xs), b.at(xs), zm});
      }
    }
    ++f.blocks;
  }
  const int n = int(od.size());
  if (n < 10) fail("the registration scan gave only ", n, " wall crossings seen by both planes");
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd y(n);
  for (int i = 0; i < n; ++i)
    A(i, 0) = 1, A(i, 1) = ox[i] / step, A(i, 2) = oz[i] / step, y(i) = od[i];
  // Heights must vary for beta; with one height it is held at zero.
  double zmin = 1e9, zmax = -1e9;
  for (double z : oz) zmin = std::min(zmin, z), zmax = std::max(zmax, z);
  const bool fit_beta = zmax - zmin > 5;
  const Eigen::MatrixXd Au = fit_beta ? A : A.leftCols(2);
  const Eigen::VectorXd s = Au.colPivHouseholderQr().solve(y);
  const Eigen::VectorXd r = y - Au * s;
  const double s2 = r.squaredNorm() / std::max(1, n - int(Au.cols()));
  const Eigen::MatrixXd C = (Au.transpose() * Au).inverse() * s2;
  f.observations = n;
  f.delay_lines = s(0);
  f.delay_std = std::sqrt(C(0, 0));
  f.alpha_deg = std::atan(s(1)) * 180 / M_PI;
  f.alpha_std = std::sqrt(C(1, 1)) * 180 / M_PI;
  if (fit_beta) {
    f.beta_deg = std::atan(s(2)) * 180 / M_PI;
    f.beta_std = std::sqrt(C(2, 2)) * 180 / M_PI;
  }
  f.rms_lines = std::sqrt(r.squaredNorm() / n);
  // Block corners: the laser's wall position mapped by the registration against the X-ray's.
  double sum = 0;
  for (const Corner& c : corners) {
    const double d = s(0) + s(1) * c.x / step + (fit_beta ? s(2) * c.z / step : 0.0);
    const double e = std::abs(c.xray - (c.laser + d)) * step;
    sum += e;
    f.corner_worst_mm = std::max(f.corner_worst_mm, e);
  }
  f.corner_mean_mm = corners.empty() ? 0 : sum / double(corners.size());
  return f;
}

SolveReport RegistrationFit::report(const std::string& subject) const {
  SolveReport r;
  r.solver = "registration";
  r.subject = subject;
  r.parameters = {{"delay_lines", delay_lines, delay_std, "lines"},
                  {"alpha_deg", alpha_deg, alpha_std, "deg"},
                  {"beta_deg", beta_deg, beta_std, "deg"}};
  r.figures = {{"blocks", double(blocks)},
               {"wall_crossings", double(observations)},
               {"rms_lines", rms_lines},
               {"wall_position_mean_mm", corner_mean_mm},
               {"wall_position_worst_mm", corner_worst_mm}};
  if (std::abs(delay_lines - std::round(delay_lines)) > 0.25)
    r.warnings.push_back(
        join("the delay is ", delay_lines, " lines; the line path registers whole lines, so up to ",
             std::abs(delay_lines - std::round(delay_lines)), " line of offset remains"));
  return r;
}

}  // namespace rangex
