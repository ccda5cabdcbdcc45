#include "calib/zhang_init.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/error.h"

namespace rangex {

namespace {

// Normalised DLT (Hartley): board (X, Y) to pixel homography.
Eigen::Matrix3d homography(const PlanarView& v) {
  const size_t n = v.board.size();
  auto normaliser = [n](auto get) {
    Eigen::Vector2d mean(0, 0);
    for (size_t i = 0; i < n; ++i) mean += get(i);
    mean /= double(n);
    double d = 0;
    for (size_t i = 0; i < n; ++i) d += (get(i) - mean).norm();
    const double s = std::sqrt(2.0) / (d / double(n));
    Eigen::Matrix3d T;
    T << s, 0, -s * mean.x(), 0, s, -s * mean.y(), 0, 0, 1;
    return T;
  };
  const Eigen::Matrix3d Tb =
      normaliser([&](size_t i) { return Eigen::Vector2d(v.board[i].x, v.board[i].y); });
  const Eigen::Matrix3d Tp =
      normaliser([&](size_t i) { return Eigen::Vector2d(v.pixels[i].x, v.pixels[i].y); });
  Eigen::MatrixXd A(2 * n, 9);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d b = Tb * Eigen::Vector3d(v.board[i].x, v.board[i].y, 1);
    const Eigen::Vector3d p = Tp * Eigen::Vector3d(v.pixels[i].x, v.pixels[i].y, 1);
    A.row(2 * i) << b.x(), b.y(), 1, 0, 0, 0, -p.x() * b.x(), -p.x() * b.y(), -p.x();
    A.row(2 * i + 1) << 0, 0, 0, b.x(), b.y(), 1, -p.y() * b.x(), -p.y() * b.y(), -p.y();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::VectorXd h = svd.matrixV().col(8);
  Eigen::Matrix3d Hn;
  Hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  const Eigen::Matrix3d H = Tp.inverse() * Hn * Tb;
  return H / H(2, 2);
}

Eigen::Matrix<double, 6, 1> vij(const Eigen::Matrix3d& H, int i, int j) {
  const Eigen::Vector3d a = H.col(i), b = H.col(j);
  Eigen::Matrix<double, 6, 1> v;
  v << a(0) * b(0), a(0) * b(1) + a(1) * b(0), a(1) * b(1), a(2) * b(0) + a(0) * b(2),
      a(2) * b(1) + a(1) * b(2), a(2) * b(2);
  return v;
}

}  // namespace

ZhangStart zhang_initialise(const std::vector<PlanarView>& views) {
  if (views.size() < 3)
    fail("too few target views: ", views.size(), " (the closed form needs at least 3)");
  std::vector<Eigen::Matrix3d> Hs;
  for (size_t k = 0; k < views.size(); ++k) {
    const PlanarView& v = views[k];
    if (v.board.size() != v.pixels.size() || v.board.size() < 4)
      fail("target view ", k, " has ", v.pixels.size(), " corners (at least 4 needed)");
    for (const Vec3& b : v.board)
      if (std::abs(b.z) > 1e-9) fail("target view ", k, ": the target is not planar (z != 0)");
    Hs.push_back(homography(v));
  }
  Eigen::MatrixXd V(2 * Hs.size(), 6);
  for (size_t k = 0; k < Hs.size(); ++k) {
    V.row(2 * k) = vij(Hs[k], 0, 1).transpose();
    V.row(2 * k + 1) = (vij(Hs[k], 0, 0) - vij(Hs[k], 1, 1)).transpose();
  }
  // Scale the columns so the singular values compare like with like (pixel units make
  // them differ by orders of magnitude).
  Eigen::Matrix<double, 6, 1> scale;
  double biggest = 0;
  for (int c = 0; c < 6; ++c) biggest = std::max(biggest, V.col(c).norm());
  // A column the views leave (nearly) empty is itself the degeneracy: do not blow it up.
  for (int c = 0; c < 6; ++c) scale(c) = 1.0 / std::max(V.col(c).norm(), 1e-6 * biggest);
  const Eigen::MatrixXd Vs = V * scale.asDiagonal();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Vs, Eigen::ComputeFullV);
  const auto& s = svd.singularValues();
  if (s(4) < 1e-9 * s(0))
    fail("degenerate target poses: the ", views.size(),
         " views do not determine the intrinsics (boards nearly parallel; tilt the target "
         "differently between views)");
  Eigen::Matrix<double, 6, 1> b = scale.asDiagonal() * svd.matrixV().col(5);
  if (b(0) < 0) b = -b;
  const double B11 = b(0), B12 = b(1), B22 = b(2), B13 = b(3), B23 = b(4), B33 = b(5);
  const double den = B11 * B22 - B12 * B12;
  const double v0 = (B12 * B13 - B11 * B23) / den;
  const double lambda = B33 - (B13 * B13 + v0 * (B12 * B13 - B11 * B23)) / B11;
  if (!(den > 0) || !(lambda / B11 > 0) || !(lambda * B11 / den > 0))
    fail("degenerate target poses: the closed form found no valid intrinsic matrix from ",
         views.size(), " views; tilt the target more between views");
  const double alpha = std::sqrt(lambda / B11);
  const double beta = std::sqrt(lambda * B11 / den);
  const double gamma = -B12 * alpha * alpha * beta / lambda;
  const double u0 = gamma * v0 / beta - B13 * alpha * alpha / lambda;
  ZhangStart z;
  z.intrinsics = {alpha, beta, u0, v0, gamma / alpha};
  Eigen::Matrix3d K;
  K << alpha, gamma, u0, 0, beta, v0, 0, 0, 1;
  const Eigen::Matrix3d Ki = K.inverse();
  for (const Eigen::Matrix3d& H : Hs) {
    Eigen::Vector3d r1 = Ki * H.col(0), r2 = Ki * H.col(1), t = Ki * H.col(2);
    double l = 1.0 / r1.norm();
    if ((l * t).z() < 0) l = -l;  // the board lies in front of the camera
    r1 *= l, r2 *= l, t *= l;
    Eigen::Matrix3d Q;
    Q.col(0) = r1, Q.col(1) = r2, Q.col(2) = r1.cross(r2);
    // Eq. 34: the nearest rotation in the Frobenius norm.
    const Eigen::JacobiSVD<Eigen::Matrix3d> qs(Q, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d R = qs.matrixU() * qs.matrixV().transpose();
    if (R.determinant() < 0) {
      Eigen::Matrix3d U = qs.matrixU();
      U.col(2) *= -1;
      R = U * qs.matrixV().transpose();
    }
    Mat3 Rm;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) Rm(i, j) = R(i, j);
    z.R.push_back(Rm);
    z.t.push_back({t.x(), t.y(), t.z()});
  }
  return z;
}

}  // namespace rangex
