// Camera extrinsics relative to the laser plane and belt from a simulated staircase scan
// (targets: worst step error <= 0.1 mm for both cameras; Table 5's worst is 0.291).
#include <gtest/gtest.h>

#include <cmath>

#include "calib/staircase_fit.h"
#include "calib_scans.h"
#include "core/error.h"

namespace rangex {
namespace {

using calib_test::across_belt_error;
using calib_test::moved_rig;
using calib_test::scan_rows;

TEST(Staircase, RecoversBothCamerasOfAMovedRig) {
  const LaneConfig nominal = default_lane_config(0);
  const LaneConfig rig = moved_rig();
  const Staircase stairs;
  const sim::CalibScene scene = sim::staircase_scene(stairs);
  for (int cam = 0; cam < 2; ++cam) {
    int64_t lines = 0;
    const auto rows = scan_rows(rig, scene, cam, &lines);
    const StaircaseFit f =
        fit_staircase(rows.data(), lines, rig.frame_width, nominal.cameras[cam].model, stairs,
                      "cam" + std::to_string(cam));
    const Vec3 dc = f.camera.center() - rig.cameras[cam].model.center();
    std::printf(
        "cam%d: %d plateaus, column-mean height RMS %.4f mm (%.3f px), edges %.3f px, "
        "worst step error %.4f mm; centre error (%.2f, %.2f, %.2f) mm\n",
        cam, f.plateaus, f.height_rms_mm, f.height_rms_px, f.edge_rms_px, f.worst_step_error_mm,
        dc.x, dc.y, dc.z);
    for (const StepStat& s : f.steps)
      std::printf("  %4.0f mm: mean %.3f std %.4f error %+.4f (%lld samples)\n", s.height_mm,
                  s.mean_mm, s.std_mm, s.error_mm, (long long)s.samples);
    EXPECT_LE(f.worst_step_error_mm, 0.1);
    EXPECT_EQ(f.steps.size(), stairs.heights_mm.size());
    // Heights anywhere on the plane agree with the true rig's (the pose is right, not
    // only fitted to the steps).
    double worst = 0;
    for (double u : {50.0, 320.0, 590.0})
      for (double v : {30.0, 100.0, 170.0}) {
        const double ht = plane_height(rig.cameras[cam].model, u, v);
        const double hf = plane_height(f.camera, u, v);
        if (std::isfinite(ht)) worst = std::max(worst, std::abs(ht - hf));
      }
    EXPECT_LT(worst, 0.15) << "height map differs from the true rig's";
    // Across the belt: where the solved camera puts stripe points against the true rig
    // (the laser's side of the laser-to-X-ray registration).
    double xworst = 0;
    const double xmean = across_belt_error(f.camera, rig.cameras[cam].model, &xworst);
    std::printf("cam%d: across the belt, solved vs true %.3f mm mean, %.3f mm worst\n", cam, xmean,
                xworst);
    EXPECT_LT(xmean, 0.3);
    EXPECT_TRUE(f.report("cam").passed);
  }
}

TEST(Staircase, AMissingStepIsNamed) {
  const LaneConfig rig = default_lane_config(0);
  Staircase drawn;
  Staircase built = drawn;
  built.heights_mm[6] = 0;  // the 35 mm block was left off
  const sim::CalibScene scene = sim::staircase_scene(built);
  int64_t lines = 0;
  const auto rows = scan_rows(rig, scene, 0, &lines);
  try {
    fit_staircase(rows.data(), lines, rig.frame_width, rig.cameras[0].model, drawn, "cam0");
    FAIL() << "a missing step was not noticed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("35"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cam0"), std::string::npos) << e.what();
  }
}

TEST(Staircase, AnEmptyScanIsRefused) {
  const LaneConfig rig = default_lane_config(0);
  int64_t lines = 0;
  std::vector<float> rows;
  {
    sim::CalibScene s;
    s.boxes.push_back({-500, -499, 0, 100, 0, 1});  // nothing under the laser
    rows = scan_rows(rig, s, 0, &lines);
  }
  EXPECT_THROW(
      fit_staircase(rows.data(), lines, rig.frame_width, rig.cameras[0].model, Staircase{}, "cam0"),
      Error);
}

}  // namespace
}  // namespace rangex
