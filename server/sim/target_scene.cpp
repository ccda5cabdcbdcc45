#include "sim/target_scene.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace rangex::sim {

std::vector<Vec3> TargetBoard::corners() const {
  std::vector<Vec3> c;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) c.push_back({i * square_mm, j * square_mm, 0});
  return c;
}

namespace {

// The board's outer edge: the pattern's squares and a white margin of one square.
std::vector<Vec3> outline(const TargetBoard& b) {
  const double s = b.square_mm, x0 = -2 * s, y0 = -2 * s, x1 = (b.cols + 1) * s,
               y1 = (b.rows + 1) * s;
  return {{x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}, {x0, y1, 0}};
}

}  // namespace

std::vector<TargetPose> random_target_poses(const CameraModel& cam, const TargetBoard& board, int n,
                                            uint64_t seed) {
  Rng rng(seed, 0x7a29e7);
  std::vector<TargetPose> poses;
  const Vec3 centre{(board.cols - 1) * board.square_mm / 2, (board.rows - 1) * board.square_mm / 2,
                    0};
  const auto corners = board.corners();
  const auto edge = outline(board);
  const double margin = 4;
  for (int tries = 0; int(poses.size()) < n; ++tries) {
    if (tries > 20000 * n) fail("cannot place ", n, " target views inside the frame");
    // Alternate strong tilts about both axes so the views constrain the focal lengths.
    const double ax = rng.uniform(-0.7, 0.7), ay = rng.uniform(-0.7, 0.7),
                 az = rng.uniform(-0.25, 0.25);
    const double z = rng.uniform(450, 700);
    // Aim the board centre at a random pixel.
    const Vec2 px{rng.uniform(0, cam.width() - 1), rng.uniform(0, cam.height() - 1)};
    const Ray r = cam.pixel_ray(px);
    // pixel_ray is in world coordinates; the generator works in camera coordinates.
    const Vec3 dir = cam.rotation() * r.dir;
    TargetPose p;
    p.R = rotation_xyz(ax, ay, az);
    p.t = dir * (z / dir.z) - p.R * centre;
    auto inside = [&](const Vec3& b) {
      const Vec3 c = p.R * b + p.t;
      if (c.z < 100) return false;
      const Vec2 q = cam.normalized_to_pixel(cam.distort({c.x / c.z, c.y / c.z}));
      return q.x >= margin && q.y >= margin && q.x <= cam.width() - 1 - margin &&
             q.y <= cam.height() - 1 - margin;
    };
    if (!std::all_of(edge.begin(), edge.end(), inside)) continue;
    if (!std::all_of(corners.begin(), corners.end(), inside)) continue;
    // The board must face the camera.
    const Vec3 normal = p.R * Vec3{0, 0, 1};
    const Vec3 to_cam = (p.R * centre + p.t) * -1.0;
    if (std::abs(normal.dot(to_cam.normalized())) < 0.5) continue;
    poses.push_back(p);
  }
  return poses;
}

TargetRenderer::TargetRenderer(const CameraModel& cam, TargetBoard board, TargetRenderParams p)
    : cam_(cam), board_(board), p_(p) {
  const int W = cam.width(), H = cam.height();
  rays_.resize(size_t(W) * H);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      auto ray = [&](double du, double dv) {
        return cam.undistort(cam.pixel_to_normalized({u + du, v + dv}));
      };
      const Vec2 c = ray(0, 0), ux = ray(0.5, 0), vx = ray(0, 0.5);
      rays_[size_t(v) * W + u] = {
          c.x, c.y, 2 * (ux.x - c.x), 2 * (ux.y - c.y), 2 * (vx.x - c.x), 2 * (vx.y - c.y)};
    }
}

void TargetRenderer::render(const TargetPose& pose, Rng& rng, uint8_t* frame,
                            std::vector<Vec2>* truth) const {
  const int W = cam_.width(), H = cam_.height(), S = p_.supersample;
  // Camera ray (x, y, 1) meets the board plane n . X = d (camera coordinates); the hit is
  // mapped back into board coordinates by R^T (X - t).
  const Vec3 n = pose.R * Vec3{0, 0, 1};
  const double d = n.dot(pose.t);
  const Mat3 Rt = pose.R.transposed();
  const double s = board_.square_mm;
  std::vector<float> img(size_t(W) * H);
  const double edge = 0.5 - 0.5 / S;  // the outermost sub-samples' offset from the centre
  // Squares -1 .. cols-1 by -1 .. rows-1 carry the pattern; one more square of white around
  // them; the rest is background.
  auto square_value = [&](double i, double j) {
    if (!(i >= -2 && i <= board_.cols && j >= -2 && j <= board_.rows)) return p_.background;
    const bool pattern = i >= -1 && i < board_.cols && j >= -1 && j < board_.rows;
    return pattern && (int64_t(i + j) & 1) == 0 ? p_.black : p_.white;
  };
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const auto& r = rays_[size_t(v) * W + u];
      // The board plane's image of the pixel is convex (the ray is affine in the offsets, and
      // the denominator keeps its sign across it). When its four outermost sub-samples lie
      // well inside one square, every sub-sample does, and each sees that square's value.
      double ci = 0, cj = 0;
      bool one_square = true, ahead = true;
      for (int c = 0; c < 4 && one_square; ++c) {
        const double du = c & 1 ? edge : -edge, dv = c & 2 ? edge : -edge;
        const Vec3 ray{r[0] + r[2] * du + r[4] * dv, r[1] + r[3] * du + r[5] * dv, 1};
        const double den = n.dot(ray);
        if (std::abs(den) < 1e-6 || (c > 0 && (den > 0) != ahead)) {
          one_square = false;
          break;
        }
        ahead = den > 0;
        const Vec3 b = Rt * (ray * (d / den) - pose.t);
        const double fx = b.x / s, fy = b.y / s;
        const double i = std::floor(fx), j = std::floor(fy);
        constexpr double kMargin = 1e-6;  // of a square: far beyond rounding
        if (fx - i < kMargin || fx - i > 1 - kMargin || fy - j < kMargin || fy - j > 1 - kMargin ||
            (c > 0 && (i != ci || j != cj)))
          one_square = false;
        ci = i, cj = j;
      }
      double sum = 0;
      if (one_square) {
        const double g = square_value(ci, cj);
        for (int k = 0; k < S * S; ++k) sum += g;  // the same additions as below
        img[size_t(v) * W + u] = float(sum / (S * S));
        continue;
      }
      for (int sy = 0; sy < S; ++sy)
        for (int sx = 0; sx < S; ++sx) {
          const double du = (sx + 0.5) / S - 0.5, dv = (sy + 0.5) / S - 0.5;
          const Vec3 ray{r[0] + r[2] * du + r[4] * dv, r[1] + r[3] * du + r[5] * dv, 1};
          const double den = n.dot(ray);
          double g = p_.background;
          if (std::abs(den) > 1e-12) {
            const Vec3 b = Rt * (ray * (d / den) - pose.t);
            g = square_value(std::floor(b.x / s), std::floor(b.y / s));
          }
          sum += g;
        }
      img[size_t(v) * W + u] = float(sum / (S * S));
    }
  // Lens and sensor blur: a separable Gaussian.
  if (p_.optics_blur_px > 0) {
    const int R = int(std::ceil(3 * p_.optics_blur_px));
    std::vector<float> k(2 * R + 1), tmp(img.size());
    float ks = 0;
    for (int i = -R; i <= R; ++i)
      ks += k[i + R] = float(std::exp(-0.5 * i * i / (p_.optics_blur_px * p_.optics_blur_px)));
    for (float& x : k) x /= ks;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        float a = 0;
        for (int i = -R; i <= R; ++i)
          a += k[i + R] * img[size_t(v) * W + std::clamp(u + i, 0, W - 1)];
        tmp[size_t(v) * W + u] = a;
      }
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        float a = 0;
        for (int i = -R; i <= R; ++i)
          a += k[i + R] * tmp[size_t(std::clamp(v + i, 0, H - 1)) * W + u];
        img[size_t(v) * W + u] = a;
      }
  }
  for (size_t i = 0; i < img.size(); ++i)
    frame[i] = uint8_t(std::clamp(std::lround(img[i] + p_.noise * rng.normal()), 0L, 255L));
  if (truth) {
    truth->clear();
    for (const Vec3& b : board_.corners()) {
      const Vec3 c = pose.R * b + pose.t;
      truth->push_back(cam_.normalized_to_pixel(cam_.distort({c.x / c.z, c.y / c.z})));
    }
  }
}

}  // namespace rangex::sim
