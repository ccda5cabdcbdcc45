#include "calib/camera_images_solve.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "calib/report_plots.h"
#include "calib/scan_lines.h"
#include "calib/target_corners.h"
#include "core/error.h"
#include "core/png_io.h"

namespace fs = std::filesystem;

namespace rangex {

TargetBoard read_target_board(const std::string& dir) {
  const YAML::Node b = YAML::Load(read_scan_drawing(dir, "board.yaml"));
  TargetBoard t;
  t.cols = b["board"]["cols"].as<int>();
  t.rows = b["board"]["rows"].as<int>();
  t.square_mm = b["board"]["square_mm"].as<double>();
  if (b["camera"]) t.camera = b["camera"].as<int>();
  return t;
}

namespace {
void warn(const CameraImagesOptions& opt, const std::string& what) {
  if (opt.warn) opt.warn(what);
}
}  // namespace

CameraImagesSolve solve_camera_from_images(const std::string& dir, LaneConfig& lane,
                                           const CameraImagesOptions& opt, const std::string& out) {
  if (opt.cam < 0 || opt.cam > 1) fail("the camera must be 0 or 1 (got ", opt.cam, ")");
  const TargetBoard tb = read_target_board(dir);
  std::vector<fs::path> images;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".png") images.push_back(e.path());
  std::sort(images.begin(), images.end());
  std::vector<TargetView> views;
  std::vector<Vec3> board;
  for (int j = 0; j < tb.rows; ++j)
    for (int i = 0; i < tb.cols; ++i) board.push_back({i * tb.square_mm, j * tb.square_mm, 0});
  for (const auto& p : images) {
    int w = 0, h = 0;
    const std::vector<uint8_t> img = read_png8_gray(p.string(), w, h);
    if (w != lane.frame_width || h != lane.frame_height)
      fail(p.string(), ": ", w, "x", h, " image, the camera is ", lane.frame_width, "x",
           lane.frame_height);
    const auto c = find_target_corners(img.data(), w, h, tb.cols, tb.rows);
    if (!c) {
      if (opt.skip_unfound) {
        warn(opt, p.string() + ": target not found, skipped");
        continue;
      }
      fail(p.string(), ": the ", tb.cols, "x", tb.rows,
           " target was not found (whole board in view, in focus, lit evenly?); "
           "--skip-unfound leaves such images out");
    }
    TargetView v{p.filename().string(), {}};
    for (size_t i = 0; i < c->size(); ++i)
      if (std::isfinite((*c)[i].x))
        v.points.board.push_back(board[i]), v.points.pixels.push_back((*c)[i]);
    if (v.points.pixels.size() < c->size())
      warn(opt, p.string() + ": " + std::to_string(c->size() - v.points.pixels.size()) +
                    " corner(s) off the board's grid left out");
    views.push_back(std::move(v));
  }
  CameraImagesSolve s;
  s.images = images.size();
  s.with_target = views.size();
  s.fit = calibrate_camera(views, lane.frame_width, lane.frame_height, opt.solve);
  const CameraFit& f = s.fit;
  const int cam = opt.cam;
  LaneCamera& lc = lane.cameras[cam];
  lc.model = CameraModel(f.intrinsics, f.distortion, lc.model.rotation(), lc.model.translation(),
                         lc.model.width(), lc.model.height());
  s.report = f.report("lane " + std::to_string(lane.id) + " cam" + std::to_string(cam));
  // The uncertainty map as an image (255 = the worst node), one pixel per node.
  std::vector<uint8_t> map(f.map.px.size());
  for (size_t i = 0; i < map.size(); ++i)
    map[i] = uint8_t(std::lround(255 * f.map.px[i] / std::max(1e-12, f.map.worst)));
  write_png8(out + ".cam" + std::to_string(cam) + "-uncertainty.png", map.data(), f.map.cols,
             f.map.rows);
  // Residuals across the sensor: every corner where it was seen (image rows down), grey
  // below the RMS, orange to 3x, red beyond.
  Series low{{}, {}, 150, 150, 150}, mid{{}, {}, 240, 140, 0}, high{{}, {}, 210, 0, 0};
  for (size_t i = 0; i < f.corner_px.size(); ++i) {
    const double e = std::hypot(f.residual_px[i].x, f.residual_px[i].y);
    Series& ser = e < f.rms_px ? low : e < 3 * f.rms_px ? mid : high;
    ser.x.push_back(f.corner_px[i].x);
    ser.y.push_back(lane.frame_height - 1 - f.corner_px[i].y);
  }
  plot_points(out + ".cam" + std::to_string(cam) + "-residuals.png", {low, mid, high}, 0,
              lane.frame_width - 1, 0, lane.frame_height - 1, 80, 50, lane.frame_width,
              lane.frame_height);
  return s;
}

}  // namespace rangex
