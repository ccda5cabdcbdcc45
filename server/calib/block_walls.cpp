#include "calib/block_walls.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "calib/open_beam.h"
#include "calib/staircase_fit.h"
#include "core/error.h"
#include "core/no_value.h"

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
  return kNaN;
}

// Where a ray from the source through detector position `i` (fractional pixel) meets
// height z.
double ray_x_at(const FanBeam& fb, double i, double z) {
  const double xd = fb.first_pixel_x_mm + fb.pitch_x() * i,
               zd = fb.detector_z_mm + fb.pitch_z() * i;
  return xd + (fb.source_x_mm - xd) * (z - zd) / (fb.source_z_mm - zd);
}

// Cosine of the ray through pixel i against the vertical: a block of height h is h / cos
// thick along it.
double ray_cos(const FanBeam& fb, int i) {
  const double dx = fb.pixel_x(i) - fb.source_x_mm, dz = fb.pixel_z(i) - fb.source_z_mm;
  return std::abs(dz) / std::hypot(dx, dz);
}

}  // namespace

WallLine robust_line(const std::vector<double>& x, const std::vector<double>& y, double reject) {
  WallLine l;
  std::vector<uint8_t> use(x.size());
  for (size_t i = 0; i < x.size(); ++i) use[i] = std::isfinite(x[i]) && std::isfinite(y[i]);
  for (int pass = 0; pass < 3; ++pass) {
    double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t i = 0; i < x.size(); ++i)
      if (use[i]) n += 1, sx += x[i], sy += y[i], sxx += x[i] * x[i], sxy += x[i] * y[i];
    const double den = n * sxx - sx * sx;
    if (n < 6 || std::abs(den) < 1e-9) return WallLine{};
    l.b = (n * sxy - sx * sy) / den;
    l.a = (sy - l.b * sx) / n;
    l.ok = true;
    const double r = pass == 0 ? reject : 0.5 * reject;
    for (size_t i = 0; i < x.size(); ++i)
      use[i] = std::isfinite(x[i]) && std::isfinite(y[i]) && std::abs(y[i] - l.at(x[i])) < r;
  }
  return l;
}

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

std::vector<BlockWalls> find_block_walls(const LaserProfiles& L, const uint16_t* xray,
                                         int64_t lines, const FanBeam& fb, const BlockSet& set) {
  const int P = fb.pixels;
  if (L.lines != lines) fail("laser and X-ray scans differ in length: ", L.lines, " vs ", lines);
  // Blocks as the laser sees them: runs of lines with a flat top above 2 mm.
  auto laser_top = [&](int64_t n) {
    int c = 0;
    for (int k = 0; k < L.n; ++k) c += L.h[n * L.n + k] > 2;
    return c >= 4;
  };
  const auto lr = runs(lines, laser_top, 5);
  // X-ray: attenuation per line and pixel against the open beam.
  const std::vector<double> open = open_beam(xray, lines, P);
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
  std::vector<BlockWalls> out;
  for (size_t k = 0; k < lr.size(); ++k) {
    const Run l = lr[k], x = xr[k];
    BlockWalls w;
    // Top height and lateral extent from the laser's middle line.
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
    w.height_mm = h;
    w.xl_mm = L.x0_mm + L.pitch_mm * kmin, w.xh_mm = L.x0_mm + L.pitch_mm * kmax;
    const double zm = 0.5 * h;
    const double reach = double(l.b - l.a) / 2 + 40;
    // Leading and trailing walls in each plane, over the block's inner width (3 mm from
    // its sides).
    std::vector<double> lx, ll, lt, px, pl, pt;
    for (int g = 0; g < L.n; ++g) {
      const double xg = L.x0_mm + L.pitch_mm * g;
      if (xg < w.xl_mm + 3 || xg > w.xh_mm - 3) continue;
      auto lv = [&](int64_t n) { return double(L.h[n * L.n + g]); };
      lx.push_back(xg);
      ll.push_back(crossing(lv, mid, -1, lines, 0.5 * h, int64_t(reach)));
      lt.push_back(crossing(lv, mid, +1, lines, 0.5 * h, int64_t(reach)));
    }
    const int64_t xmid = (x.a + x.b) / 2;
    for (int i = 0; i < P; ++i) {
      const double xm = ray_x_at(fb, i, zm);
      if (xm < w.xl_mm + 3 || xm > w.xh_mm - 3) continue;
      const double plateau = att(xmid, i);
      auto xv = [&](int64_t n) { return att(n, i); };
      px.push_back(xm);
      pl.push_back(crossing(xv, xmid, -1, lines, 0.5 * plateau, int64_t(reach)));
      pt.push_back(crossing(xv, xmid, +1, lines, 0.5 * plateau, int64_t(reach)));
    }
    w.laser_lead = robust_line(lx, ll, 3.0), w.laser_trail = robust_line(lx, lt, 3.0);
    w.xray_lead = robust_line(px, pl, 3.0), w.xray_trail = robust_line(px, pt, 3.0);
    if (!w.laser_lead.ok || !w.laser_trail.ok || !w.xray_lead.ok || !w.xray_trail.ok)
      fail("block ", k, " (", set.blocks[k].height_mm,
           " mm): its leading or trailing wall could not be located in ",
           !w.laser_lead.ok || !w.laser_trail.ok ? "the laser scan" : "the X-ray");
    // Lines clear of the leading and trailing walls (the corners reach a little past the
    // middle line's extent; 4 lines of margin for the blur).
    auto clear = [&](const WallLine& lead, const WallLine& trail, int64_t& first, int64_t& last) {
      const double a = std::max(lead.at(w.xl_mm - 3), lead.at(w.xh_mm + 3)),
                   b = std::min(trail.at(w.xl_mm - 3), trail.at(w.xh_mm + 3));
      first = int64_t(std::ceil(a)) + 4, last = int64_t(std::floor(b)) - 4;
    };
    clear(w.laser_lead, w.laser_trail, w.laser_side_first, w.laser_side_last);
    clear(w.xray_lead, w.xray_trail, w.xray_side_first, w.xray_side_last);
    // Side walls in the X-ray, per line: where the attenuation falls to half the block's
    // full thickness along that pixel's ray (the ray then meets the wall at mid-height).
    std::vector<double> sn, slo, shi;
    for (int64_t n = std::max<int64_t>(0, w.xray_side_first);
         n <= std::min(lines - 1, w.xray_side_last); ++n) {
      double amax = 0;
      for (int i = 0; i < P; ++i) amax = std::max(amax, att(n, i));
      int best0 = -1, best1 = -2;
      for (int i = 0; i < P;) {  // the longest run above half the line's maximum
        if (att(n, i) <= 0.5 * amax) {
          ++i;
          continue;
        }
        int e = i;
        while (e + 1 < P && att(n, e + 1) > 0.5 * amax) ++e;
        if (e - i > best1 - best0) best0 = i, best1 = e;
        i = e + 1;
      }
      if (best1 - best0 < 8 || best0 == 0 || best1 == P - 1) continue;
      const int third = (best1 - best0) / 3;
      std::vector<double> mids;
      for (int i = best0 + third; i <= best1 - third; ++i)
        mids.push_back(att(n, i) * ray_cos(fb, i));
      std::nth_element(mids.begin(), mids.begin() + mids.size() / 2, mids.end());
      const double full = mids[mids.size() / 2];  // attenuation per unit of h / cos
      const int ic = (best0 + best1) / 2;
      double edge[2] = {kNaN, kNaN};
      for (int s = 0; s < 2; ++s) {
        const int dir = s ? 1 : -1;
        for (int i = ic; i + dir >= 0 && i + dir < P; i += dir) {
          const double la = 0.5 * full / ray_cos(fb, i), lb = 0.5 * full / ray_cos(fb, i + dir);
          const double a = att(n, i) - la, b = att(n, i + dir) - lb;
          if (a > 0 && b <= 0) {
            edge[s] = ray_x_at(fb, i + dir * a / (a - b), zm);
            break;
          }
        }
      }
      sn.push_back(double(n)), slo.push_back(edge[0]), shi.push_back(edge[1]);
    }
    w.xray_low = robust_line(sn, slo, 1.0), w.xray_high = robust_line(sn, shi, 1.0);
    if (!w.xray_low.ok || !w.xray_high.ok)
      fail("block ", k, " (", set.blocks[k].height_mm,
           " mm): its side walls could not be located in the X-ray (is the block longer "
           "than it is askew?)");
    out.push_back(w);
  }
  return out;
}

TopView camera_top_view(const float* rows, int width, const CameraModel& cam, const BlockWalls& b) {
  TopView view;
  const double H = b.height_mm, tol = std::max(1.0, 0.05 * H);
  const bool u_with_x = cam.project({10, 0, H}).x > cam.project({0, 0, H}).x;
  std::vector<double> h(width);
  for (int64_t n = b.laser_side_first; n <= b.laser_side_last; ++n) {
    const float* r = rows + n * width;
    for (int u = 0; u < width; ++u) h[u] = std::isfinite(r[u]) ? plane_height(cam, u, r[u]) : kNaN;
    auto on_top = [&](int u) { return std::isfinite(h[u]) && std::abs(h[u] - H) < tol; };
    // The longest run of top columns, bridging gaps of up to two lost columns.
    int best0 = -1, best1 = -2;
    for (int u = 0; u < width;) {
      if (!on_top(u)) {
        ++u;
        continue;
      }
      int e = u;
      for (;;) {
        int nx = e + 1;
        while (nx < width && nx <= e + 3 && !std::isfinite(h[nx])) ++nx;
        if (nx < width && nx <= e + 3 && on_top(nx))
          e = nx;
        else
          break;
      }
      if (e - u > best1 - best0) best0 = u, best1 = e;
      u = e + 1;
    }
    if (best1 - best0 < 8) continue;
    for (int u = best0 + 3; u <= best1 - 3; u += 2)
      if (on_top(u)) view.top.push_back({double(u), double(r[u])});
    // A side counts where the top gives way to something clearly lower within a few
    // columns (not the image's edge, not a long stretch of lost stripe).
    for (int end = 0; end < 2; ++end) {
      const int u = end ? best1 : best0, dir = end ? 1 : -1;
      int nx = u + dir;
      while (nx >= 0 && nx < width && !std::isfinite(h[nx]) && std::abs(nx - u) <= 6) nx += dir;
      if (nx < 0 || nx >= width || !std::isfinite(h[nx]) || h[nx] > 0.5 * H) continue;
      TopEdge e;
      e.line = n;
      e.u = u, e.v = r[u];
      e.outward = dir;
      e.side = (dir > 0) == u_with_x ? 1 : 0;
      view.edges.push_back(e);
    }
  }
  return view;
}

}  // namespace rangex
