#include "calib/target_corners.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rangex {

namespace {

// A checkerboard corner: two edges through (u0, v0) at angles t1, t2; the intensity is
// m + a erf(d1 / s) erf(d2 / s), d the signed distances to the edges (s: the blur).
struct SaddleCost {
  const uint8_t* img;
  int width, u_lo, u_hi, v_lo, v_hi;
  bool operator()(const double* p, double* r) const {
    const double n1x = -std::sin(p[2]), n1y = std::cos(p[2]);
    const double n2x = -std::sin(p[3]), n2y = std::cos(p[3]);
    const double s = std::abs(p[4]) + 0.2;
    int k = 0;
    for (int v = v_lo; v <= v_hi; ++v)
      for (int u = u_lo; u <= u_hi; ++u, ++k) {
        const double du = u - p[0], dv = v - p[1];
        const double model =
            p[5] + p[6] * std::erf((du * n1x + dv * n1y) / s) * std::erf((du * n2x + dv * n2y) / s);
        r[k] = model - img[size_t(v) * width + u];
      }
    return true;
  }
};

// Refines a corner by fitting the saddle model over a window (wx, wy half sizes); the
// edge directions start from the neighbouring corners. Keeps the start when the fit fails
// or moves by more than a pixel.
void refine_saddle(const cv::Mat& img, cv::Point2f& c, double t1, double t2, int wx, int wy) {
  const int u_lo = int(std::lround(c.x)) - wx, u_hi = int(std::lround(c.x)) + wx;
  const int v_lo = int(std::lround(c.y)) - wy, v_hi = int(std::lround(c.y)) + wy;
  if (u_lo < 0 || v_lo < 0 || u_hi >= img.cols || v_hi >= img.rows) return;
  // m and a by least squares with the edges fixed at the start.
  double p[7] = {c.x, c.y, t1, t2, 1.0, 0, 0};
  {
    double n = 0, sf = 0, sff = 0, sy = 0, sfy = 0;
    for (int v = v_lo; v <= v_hi; ++v)
      for (int u = u_lo; u <= u_hi; ++u) {
        const double du = u - c.x, dv = v - c.y;
        const double f = std::erf((-du * std::sin(t1) + dv * std::cos(t1))) *
                         std::erf((-du * std::sin(t2) + dv * std::cos(t2)));
        const double y = img.at<uint8_t>(v, u);
        n += 1, sf += f, sff += f * f, sy += y, sfy += f * y;
      }
    const double den = n * sff - sf * sf;
    if (std::abs(den) < 1e-9) return;
    p[6] = (n * sfy - sf * sy) / den;
    p[5] = (sy - p[6] * sf) / n;
  }
  const int nres = (u_hi - u_lo + 1) * (v_hi - v_lo + 1);
  ceres::Problem problem;
  problem.AddResidualBlock(
      new ceres::NumericDiffCostFunction<SaddleCost, ceres::CENTRAL, ceres::DYNAMIC, 7>(
          new SaddleCost{img.ptr<uint8_t>(), img.cols, u_lo, u_hi, v_lo, v_hi},
          ceres::TAKE_OWNERSHIP, nres),
      nullptr, p);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 30;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &problem, &sum);
  if (!sum.IsSolutionUsable() || std::hypot(p[0] - c.x, p[1] - c.y) > 1.0) return;
  c.x = float(p[0]);
  c.y = float(p[1]);
}

}  // namespace

void drop_off_grid_corners(std::vector<Vec2>& pts, int cols, int rows) {
  // The board is a plane: a homography fitted by RANSAC maps it onto the image to within
  // the lens' distortion over the board (well under the threshold); a corner found on the
  // wrong feature lies beyond it.
  std::vector<cv::Point2f> board, image;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      board.emplace_back(float(i), float(j));
      const Vec2& p = pts[size_t(j) * cols + i];
      image.emplace_back(float(p.x), float(p.y));
    }
  std::vector<uchar> inlier;
  const cv::Mat H = cv::findHomography(board, image, cv::RANSAC, 1.5, inlier);
  if (H.empty()) return;
  for (size_t k = 0; k < pts.size(); ++k)
    if (!inlier[k]) pts[k] = {std::nan(""), std::nan("")};
}

std::optional<std::vector<Vec2>> find_target_corners(const uint8_t* frame, int width, int height,
                                                     int cols, int rows) {
  const cv::Mat img(height, width, CV_8UC1, const_cast<uint8_t*>(frame));
  std::vector<cv::Point2f> pts;
  const int flags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  if (!cv::findChessboardCorners(img, cv::Size(cols, rows), pts, flags)) return std::nullopt;
  // The squares are about 15 px tall on this sensor (fy is half of fx): a 9x9 window stays
  // inside one square's neighbourhood.
  cv::cornerSubPix(img, pts, cv::Size(4, 4), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  // cornerSubPix leaves about 0.05 px here (the squares are small and skewed); fitting the
  // corner's own model over a window brings it to about 0.02 px.
  const std::vector<cv::Point2f> start = pts;
  auto at = [&](int i, int j) { return start[size_t(j) * cols + i]; };
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      const int i0 = std::max(i - 1, 0), i1 = std::min(i + 1, cols - 1);
      const int j0 = std::max(j - 1, 0), j1 = std::min(j + 1, rows - 1);
      const cv::Point2f a = (at(i1, j) - at(i0, j)) / float(i1 - i0);  // one square along a row
      const cv::Point2f b = (at(i, j1) - at(i, j0)) / float(j1 - j0);  // one square down
      // The window stays within 40 % of a square of the corner in each image direction.
      const double sx = std::min(std::abs(a.x) + std::abs(b.x), std::abs(a.x));
      const double sy = std::min(std::abs(a.y) + std::abs(b.y), std::abs(b.y));
      const int wx = std::clamp(int(0.4 * sx), 3, 8), wy = std::clamp(int(0.4 * sy), 2, 6);
      refine_saddle(img, pts[size_t(j) * cols + i], std::atan2(a.y, a.x), std::atan2(b.y, b.x), wx,
                    wy);
    }
  std::vector<Vec2> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back({p.x, p.y});
  drop_off_grid_corners(out, cols, rows);
  return out;
}

}  // namespace rangex
