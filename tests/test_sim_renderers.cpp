// The simulator's renderers against plain references: a target image equals every sub-sample
// of every pixel taken one by one (the renderer takes a pixel that lies inside one square
// whole); a calibration scan's X-ray line sees every object its plane crosses and none it
// does not (the renderer leaves out objects beyond the line's rays); a fillet's X-ray line
// gives each pixel the path of the walk through the scene's slice (the renderer skips the
// walk for rays over the bare belt).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/lane_config.h"
#include "core/ray_path.h"
#include "sim/calib_objects.h"
#include "sim/calib_xray_renderer.h"
#include "sim/lane_scene.h"
#include "sim/target_scene.h"
#include "sim/xray_renderer.h"

namespace rangex {
namespace {

// The renderer's model of a pixel (its ray linearised across the pixel, S x S sub-samples),
// written out plainly.
std::vector<uint8_t> target_by_sub_samples(const CameraModel& cam, const sim::TargetBoard& board,
                                           const sim::TargetPose& pose,
                                           const sim::TargetRenderParams& p) {
  const int W = cam.width(), H = cam.height(), S = p.supersample;
  const Vec3 n = pose.R * Vec3{0, 0, 1};
  const double d = n.dot(pose.t), s = board.square_mm;
  const Mat3 Rt = pose.R.transposed();
  std::vector<uint8_t> out(size_t(W) * H);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      auto ray = [&](double du, double dv) {
        return cam.undistort(cam.pixel_to_normalized({u + du, v + dv}));
      };
      const Vec2 c = ray(0, 0), ux = ray(0.5, 0), vx = ray(0, 0.5);
      const double r[6] = {
          c.x, c.y, 2 * (ux.x - c.x), 2 * (ux.y - c.y), 2 * (vx.x - c.x), 2 * (vx.y - c.y)};
      double sum = 0;
      for (int sy = 0; sy < S; ++sy)
        for (int sx = 0; sx < S; ++sx) {
          const double du = (sx + 0.5) / S - 0.5, dv = (sy + 0.5) / S - 0.5;
          const Vec3 q{r[0] + r[2] * du + r[4] * dv, r[1] + r[3] * du + r[5] * dv, 1};
          const double den = n.dot(q);
          double g = p.background;
          if (std::abs(den) > 1e-12) {
            const Vec3 b = Rt * (q * (d / den) - pose.t);
            const double i = std::floor(b.x / s), j = std::floor(b.y / s);
            if (i >= -2 && i <= board.cols && j >= -2 && j <= board.rows)
              g = i >= -1 && i < board.cols && j >= -1 && j < board.rows &&
                          (int64_t(i + j) & 1) == 0
                      ? p.black
                      : p.white;
          }
          sum += g;
        }
      out[size_t(v) * W + u] = uint8_t(std::clamp(std::lround(float(sum / (S * S))), 0L, 255L));
    }
  return out;
}

TEST(SimRenderers, TargetImageEqualsEverySubSampleTakenApart) {
  const LaneConfig lane = default_lane_config(0);
  const CameraModel& cam = lane.cameras[1].model;
  const sim::TargetBoard board;
  sim::TargetRenderParams p;
  p.noise = 0, p.optics_blur_px = 0;  // the geometry alone
  const sim::TargetRenderer renderer(cam, board, p);
  for (const sim::TargetPose& pose : sim::random_target_poses(cam, board, 2, 5)) {
    std::vector<uint8_t> frame(size_t(cam.width()) * cam.height());
    sim::Rng rng(5, 0);
    renderer.render(pose, rng, frame.data(), nullptr);
    const std::vector<uint8_t> want = target_by_sub_samples(cam, board, pose, p);
    size_t differ = 0, edges = 0, whole = 0;
    for (size_t i = 0; i < frame.size(); ++i) {
      differ += frame[i] != want[i];
      const bool flat = want[i] == p.black || want[i] == p.white || want[i] == p.background;
      edges += !flat, whole += flat;
    }
    EXPECT_EQ(differ, 0u);
    // Both kinds of pixel are there: those inside one square and those across an edge.
    EXPECT_GT(edges, 1000u);
    EXPECT_GT(whole, 10 * edges);
  }
}

// One X-ray line at belt offset s of a scene, without noise.
std::vector<uint16_t> xray_line(const LaneConfig& lane, const sim::CalibScene& scene, double s) {
  sim::XrayRenderParams xp;
  xp.photons_per_dn = 1e12, xp.electronic_noise = 0;
  const sim::CalibXrayRenderer r(lane, sim::XrayOptics{}, xp);
  std::vector<uint16_t> line(size_t(lane.xray.pixels));
  sim::Rng rng(1, 2);
  r.render(scene, s, rng, line.data());
  return line;
}

TEST(SimRenderers, AnXrayLineSeesWhatItsPlaneCrossesAndNothingElse) {
  const LaneConfig lane = default_lane_config(0);
  const sim::CalibXrayRenderer probe(lane, sim::XrayOptics{});
  const double plane = probe.plane_y(0, 0);  // a plane parallel to the laser's: one b a line
  // A block set askew by 8 degrees: its corners reach 0.5 (w sin + l cos) from its centre
  // along the belt, beyond its own length.
  const double yaw = 8 * M_PI / 180, w = 40, l = 30;
  sim::CalibScene one;
  one.boxes.push_back({-20, -20 + w, 100, 100 + l, 0, 20, yaw});
  const double cb = 100 + 0.5 * l;
  const double reach = 0.5 * (w * std::sin(yaw) + l * std::cos(yaw));
  const uint16_t open = xray_line(lane, {}, plane + cb).front();
  auto darkest = [&](const sim::CalibScene& sc, double b) {
    const auto line = xray_line(lane, sc, plane + b);
    return *std::min_element(line.begin(), line.end());
  };
  // Near its far corners, where an unturned box would not reach, the line is shadowed.
  for (double at : {cb - 0.95 * reach, cb + 0.95 * reach}) {
    EXPECT_GT(std::abs(at - cb), 0.5 * l);
    EXPECT_LT(darkest(one, at), 0.95 * open) << "b " << at;
  }
  // Beyond them it is not.
  for (double at : {cb - 1.05 * reach, cb + 1.05 * reach}) EXPECT_EQ(darkest(one, at), open);
  // Objects elsewhere on the belt change no line that does not reach them, to the bit.
  sim::CalibScene more = one;
  more.boxes.push_back({-50, 50, 400, 420, 0, 30, -0.1});
  more.pins.push_back({0, 30, 1.5, 600, 640});
  more.pins.push_back({10, 5, 1.0, -80, -40});
  for (double at : {cb - 0.95 * reach, cb, cb + 0.5 * reach})
    EXPECT_EQ(xray_line(lane, one, plane + at), xray_line(lane, more, plane + at)) << "b " << at;
  // And a pin is seen along its whole length, to its ends.
  sim::CalibScene pin;
  pin.pins.push_back({0, 30, 1.5, 600, 640});
  EXPECT_LT(darkest(pin, 600.05), 0.95 * open);
  EXPECT_LT(darkest(pin, 639.95), 0.95 * open);
  EXPECT_EQ(darkest(pin, 640.5), open);
}

TEST(SimRenderers, AFilletsXrayLineHoldsTheWalksPathAtEveryPixel) {
  const LaneConfig lane = default_lane_config(0);
  sim::SceneParams sp;
  sp.fillets = 2;
  const sim::LaneScene scene(21, 0, sp);
  const sim::XrayRenderer xr(lane);
  const FanBeam& fb = lane.xray;
  constexpr int kSlice = 1101;  // the renderer's slice: kLaneX0Mm .. +220 mm
  std::vector<uint16_t> line(size_t(fb.pixels));
  std::vector<float> thickness(size_t(fb.pixels)), h(kSlice);
  size_t meat = 0, belt = 0, differ = 0;
  for (double at = 0; at < scene.end_b(); at += 3.1) {
    const double s = at + xr.plane_y(0, 0), b = s - xr.plane_y(0, 0);  // as the renderer cuts
    sim::Rng rng(3, uint64_t(at * 10));
    xr.render(scene, s, rng, line.data(), thickness.data());
    scene.slice(b, h.data(), kSlice);
    const float top = *std::max_element(h.begin(), h.end());
    const ProfileGrid grid{h.data(), nullptr, kSlice, sim::kLaneX0Mm, sim::kRasterPitchMm, top};
    for (int i = 0; i < fb.pixels; ++i) {
      const float want =
          float(ray_path_length(grid, fb.pixel_x(i), fb.pixel_z(i), fb.source_x_mm, fb.source_z_mm)
                    .length_mm);
      differ += thickness[size_t(i)] != want;
      (want > 0 ? meat : belt) += 1;
    }
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(meat, 10000u);
  EXPECT_GT(belt, 10000u);
}

// Random rectangles over [x0, x1] x [b0, b1], up to `size` mm a side: wherever the scene says
// one is bare, every sample in it has height 0; both answers come often.
template <typename Scene>
void expect_bare_where_said(const Scene& scene, double x0, double x1, double b0, double b1,
                            double size, uint64_t seed) {
  sim::Rng rng(seed, 1);
  int bare = 0, not_bare = 0;
  for (int k = 0; k < 2000; ++k) {
    const double x = rng.uniform(x0, x1), b = rng.uniform(b0, b1);
    const double w = rng.uniform(0, size), l = rng.uniform(0, size);
    if (!scene.bare(x, x + w, b, b + l)) {
      ++not_bare;
      continue;
    }
    ++bare;
    for (double u = x; u <= x + w; u += 0.1)
      for (double v = b; v <= b + l; v += 0.1) ASSERT_EQ(scene.height(u, v), 0.f) << u << " " << v;
  }
  EXPECT_GT(bare, 100);
  EXPECT_GT(not_bare, 100);
}

// The camera's occlusion walks skip a walk whose steps all land where the scene says the
// belt is bare: it must never say so where a fillet or a block stands.
TEST(SimRenderers, BareBeltIsBareWhereverItIsSaidToBe) {
  sim::SceneParams sp;
  sp.fillets = 3;
  const sim::LaneScene scene(7, 0, sp);
  expect_bare_where_said(scene, -110, 110, -20, scene.end_b() + 20, 30, 7);
  // Where there is meat, it is not bare.
  const sim::Fillet& f = scene.fillets().front();
  const double cx = 0.5 * (f.x_min + f.x_max), cb = 0.5 * (f.b_min + f.b_max);
  ASSERT_GT(scene.height(cx, cb), 0.f);
  EXPECT_FALSE(scene.bare(cx - 0.01, cx + 0.01, cb - 0.01, cb + 0.01));
}

TEST(SimRenderers, BareAroundTurnedBlocksIsBareWhereverItIsSaidToBe) {
  sim::CalibScene scene;
  scene.boxes.push_back({-20, 20, 100, 130, 0, 20, 8 * M_PI / 180});
  scene.boxes.push_back({30, 60, 200, 215, 0, 10, -0.15});
  expect_bare_where_said(scene, -80, 80, 60, 260, 20, 8);
  EXPECT_FALSE(scene.bare(-0.01, 0.01, 114.99, 115.01));  // the first block's centre
}

}  // namespace
}  // namespace rangex
