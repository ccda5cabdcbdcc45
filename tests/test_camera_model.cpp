// The camera model against OpenCV's projectPoints / undistortPoints (same convention).
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <random>

#include "core/camera_model.h"
#include "core/lane_config.h"

using namespace rangex;

namespace {

cv::Mat K_of(const CameraModel& c) {
  const auto& k = c.intrinsics();
  return (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
}
cv::Mat D_of(const CameraModel& c) {
  const auto& d = c.distortion();
  return (cv::Mat_<double>(1, 5) << d.k1, d.k2, d.p1, d.p2, d.k3);
}

// The dissertation's cameras, plus one with tangential and k3 terms.
std::vector<CameraModel> cameras() {
  const LaneConfig lc = default_lane_config(0);
  std::vector<CameraModel> v{lc.cameras[0].model, lc.cameras[1].model};
  const CameraModel& c0 = lc.cameras[0].model;
  v.emplace_back(Intrinsics{1500, 1480, 330.2, 95.7, 0}, Distortion{-0.3, 0.4, 1e-3, -2e-3, -0.5},
                 c0.rotation(), c0.translation(), 640, 200);
  return v;
}

}  // namespace

TEST(CameraModel, ProjectMatchesOpenCV) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-100, 100), uz(0, 60), uy(-2, 2);
  for (const CameraModel& cam : cameras()) {
    std::vector<cv::Point3d> pts;
    for (int i = 0; i < 2000; ++i) pts.emplace_back(ux(rng), uy(rng), uz(rng));
    cv::Mat R(3, 3, CV_64F), rvec;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R.at<double>(r, c) = cam.rotation()(r, c);
    cv::Rodrigues(R, rvec);
    const cv::Mat tvec =
        (cv::Mat_<double>(3, 1) << cam.translation().x, cam.translation().y, cam.translation().z);
    std::vector<cv::Point2d> ref;
    cv::projectPoints(pts, rvec, tvec, K_of(cam), D_of(cam), ref);
    double worst = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      const Vec2 p = cam.project({pts[i].x, pts[i].y, pts[i].z});
      worst = std::max({worst, std::abs(p.x - ref[i].x), std::abs(p.y - ref[i].y)});
    }
    EXPECT_LT(worst, 1e-6) << "worst projection difference to cv::projectPoints, px";
  }
}

TEST(CameraModel, UndistortMatchesOpenCV) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uu(0, 639), uv(0, 199);
  for (const CameraModel& cam : cameras()) {
    std::vector<cv::Point2d> px;
    for (int i = 0; i < 2000; ++i) px.emplace_back(uu(rng), uv(rng));
    std::vector<cv::Point2d> ref;
    cv::undistortPoints(
        px, ref, K_of(cam), D_of(cam), cv::noArray(), K_of(cam),
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-15));
    double worst = 0;
    for (size_t i = 0; i < px.size(); ++i) {
      const Vec2 ideal = cam.undistort(cam.pixel_to_normalized({px[i].x, px[i].y}));
      const Vec2 p = {cam.intrinsics().fx * ideal.x + cam.intrinsics().cx,
                      cam.intrinsics().fy * ideal.y + cam.intrinsics().cy};
      worst = std::max({worst, std::abs(p.x - ref[i].x), std::abs(p.y - ref[i].y)});
    }
    EXPECT_LT(worst, 1e-6) << "worst undistortion difference to cv::undistortPoints, px";
  }
}

TEST(CameraModel, SkewAndRayRoundTrip) {
  const CameraModel base = default_lane_config(0).cameras[0].model;
  Intrinsics k = base.intrinsics();
  k.skew = 0.003;
  const CameraModel cam(k, base.distortion(), base.rotation(), base.translation(), 640, 200);
  for (double u : {0.0, 100.5, 319.5, 639.0})
    for (double v : {0.0, 57.25, 199.0}) {
      const Ray r = cam.pixel_ray({u, v});
      const Vec2 back = cam.project(r.origin + r.dir * 600.0);
      EXPECT_NEAR(back.x, u, 1e-7);
      EXPECT_NEAR(back.y, v, 1e-7);
    }
}
