// calib camera|staircase|xray|registration|validate: the integrator's solves. Each reads
// the lane's current calibration (--calibration FILE, else the plant's lane), solves one
// part from a scan, prints the report and writes the updated calibration to --out with
// its report beside it (FILE.reports/).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "args.h"
#include "calib/camera_intrinsics.h"
#include "calib/fan_beam_fit.h"
#include "calib/pin_shadows.h"
#include "calib/registration_fit.h"
#include "calib/staircase_fit.h"
#include "calib/target_corners.h"
#include "calib/xray_blur.h"
#include "calib_rig.h"
#include "commands.h"
#include "core/error.h"
#include "core/png_io.h"
#include "core/recording.h"
#include "pipeline/stripe_extract.h"
#include "report_plots.h"
#include "text_file.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

// An object's drawing beside its scan.
std::string read_drawing(const fs::path& p) {
  return read_text_file(p.string(), "the object's drawing belongs beside the scan");
}

void print_report(const SolveReport& r) {
  std::printf("%s", reports_json({r}).c_str());
  for (const auto& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!r.passed)
    for (const auto& f : r.failures) std::fprintf(stderr, "FAILED: %s\n", f.c_str());
}

// Both cameras' plain-centroid stripe rows of one lane (machined objects do not scatter).
std::vector<float> stripe_rows(const RecordingReader& rec, int lane, int cam,
                               const StripeParams& params) {
  const RecordingInfo& info = rec.info();
  const int W = info.width, H = info.height;
  StripeSlot slot{params, {}};
  slot.params.method = StripeMethod::kCentroid;
  std::vector<uint8_t> frames(size_t(W) * H * 64);
  std::vector<int> slots(64, 0);
  StripeOutput so;
  std::vector<float> rows;
  rows.reserve(size_t(info.lines) * W);
  for (int64_t n0 = 0; n0 < info.lines; n0 += 64) {
    const int count = int(std::min<int64_t>(64, info.lines - n0));
    rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
             cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
    extract_stripes(frames.data(), count, W, H, slots.data(), &slot, so);
    for (size_t i = 0; i < size_t(count) * W; ++i)
      rows.push_back(so.valid[i] ? so.row[i] : std::nanf(""));
  }
  return rows;
}

std::vector<uint16_t> xray_lines(const RecordingReader& rec, int lane) {
  const RecordingInfo& info = rec.info();
  std::vector<uint16_t> x(size_t(info.lines) * info.xray_pixels);
  rec.read(lane, 0, info.lines, nullptr, nullptr, x.data(), nullptr);
  return x;
}

// The registration of a blocks scan (its drawing beside it) under the lane's calibration.
RegistrationFit measure_registration(const RecordingReader& rec, int lane, const LaneConfig& lc,
                                     const RegistrationOptions& opt) {
  const BlockSet set =
      parse_block_set(read_drawing(fs::path(rec.dir()) / "blocks.yaml"), "blocks.yaml");
  const auto r0 = stripe_rows(rec, lane, 0, lc.stripe), r1 = stripe_rows(rec, lane, 1, lc.stripe);
  const auto x = xray_lines(rec, lane);
  RegistrationScan scan;
  scan.rows[0] = r0.data(), scan.rows[1] = r1.data();
  scan.width = rec.info().width;
  scan.xray = x.data();
  scan.lines = rec.info().lines;
  return fit_registration(scan, lc.cameras[0].model, lc.cameras[1].model, lc.xray,
                          lc.encoder_step_mm, set, opt);
}

struct Session {
  PlantConfig plant;
  LaneConfig lane;
  std::string out;
};

Session open_session(const Args& a, int lane) {
  Session s;
  s.plant = load_config(a.get("config", ""));
  s.lane = load_lane_calibration(s.plant, lane, a.get("calibration", ""));
  s.out = a.get("out", a.get("calibration", "lane" + std::to_string(lane) + ".calib.yaml"));
  return s;
}

int solve_camera(int argc, char** argv) {
  const Args a(argc, argv, 3, {"skip-unfound"},
               {"config", "lane", "cam", "calibration", "out", "fix"});
  a.expect_positionals(1, "calib camera DIR [--cam N] [--calibration FILE] [--out FILE]");
  const fs::path dir = a.positional(0, "image folder");
  const YAML::Node b = YAML::Load(read_drawing(dir / "board.yaml"));
  const int cols = b["board"]["cols"].as<int>(), rows = b["board"]["rows"].as<int>();
  const double square = b["board"]["square_mm"].as<double>();
  const int cam = int(a.integer("cam", b["camera"] ? b["camera"].as<int>() : 0));
  if (cam < 0 || cam > 1) fail("--cam must be 0 or 1");
  Session s = open_session(a, int(a.integer("lane", 0)));
  std::vector<fs::path> images;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".png") images.push_back(e.path());
  std::sort(images.begin(), images.end());
  std::vector<TargetView> views;
  std::vector<Vec3> board;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) board.push_back({i * square, j * square, 0});
  for (const auto& p : images) {
    const cv::Mat img = cv::imread(p.string(), cv::IMREAD_GRAYSCALE);
    if (img.empty()) fail(p.string(), ": cannot read the image");
    if (img.cols != s.lane.frame_width || img.rows != s.lane.frame_height)
      fail(p.string(), ": ", img.cols, "x", img.rows, " image, the camera is ", s.lane.frame_width,
           "x", s.lane.frame_height);
    const auto c = find_target_corners(img.ptr<uint8_t>(), img.cols, img.rows, cols, rows);
    if (!c) {
      if (a.flag("skip-unfound")) {
        std::fprintf(stderr, "warning: %s: target not found, skipped\n", p.string().c_str());
        continue;
      }
      fail(p.string(), ": the ", cols, "x", rows,
           " target was not found (whole board in view, in focus, lit evenly?); "
           "--skip-unfound leaves such images out");
    }
    TargetView v{p.filename().string(), {}};
    for (size_t i = 0; i < c->size(); ++i)
      if (std::isfinite((*c)[i].x))
        v.points.board.push_back(board[i]), v.points.pixels.push_back((*c)[i]);
    if (v.points.pixels.size() < c->size())
      std::fprintf(stderr, "warning: %s: %zu corner(s) off the board's grid left out\n",
                   p.string().c_str(), c->size() - v.points.pixels.size());
    views.push_back(std::move(v));
  }
  std::printf("# %zu of %zu images with the target; solving cam%d\n", views.size(), images.size(),
              cam);
  CameraSolveOptions opt;
  // --fix k3,p1,p2,skew: parameters held (distortion terms at 0, skew at 0).
  {
    std::stringstream list(a.get("fix", ""));
    std::string name;
    while (std::getline(list, name, ',')) {
      const auto& names = CameraFit::kNames;
      const auto it = std::find(names.begin(), names.end(), name);
      if (it == names.end() || it - names.begin() < 4)
        fail("--fix: '", name, "' is not a parameter that can be held (skew, k1, k2, p1, p2, k3)");
      opt.fixed[size_t(it - names.begin())] = true;
    }
  }
  opt.progress = [](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); };
  const CameraFit f = calibrate_camera(views, s.lane.frame_width, s.lane.frame_height, opt);
  LaneCamera& lc = s.lane.cameras[cam];
  lc.model = CameraModel(f.intrinsics, f.distortion, lc.model.rotation(), lc.model.translation(),
                         lc.model.width(), lc.model.height());
  const SolveReport r =
      f.report("lane " + std::to_string(s.lane.id) + " cam" + std::to_string(cam));
  print_report(r);
  // The uncertainty map as an image (255 = the worst node), one pixel per node.
  std::vector<uint8_t> map(f.map.px.size());
  for (size_t i = 0; i < map.size(); ++i)
    map[i] = uint8_t(std::lround(255 * f.map.px[i] / std::max(1e-12, f.map.worst)));
  write_png8(s.out + ".cam" + std::to_string(cam) + "-uncertainty.png", map.data(), f.map.cols,
             f.map.rows);
  // Residuals across the sensor: every corner where it was seen (image rows down), grey
  // below the RMS, orange to 3x, red beyond.
  {
    Series low{{}, {}, 150, 150, 150}, mid{{}, {}, 240, 140, 0}, high{{}, {}, 210, 0, 0};
    for (size_t i = 0; i < f.corner_px.size(); ++i) {
      const double e = std::hypot(f.residual_px[i].x, f.residual_px[i].y);
      Series& ser = e < f.rms_px ? low : e < 3 * f.rms_px ? mid : high;
      ser.x.push_back(f.corner_px[i].x);
      ser.y.push_back(s.lane.frame_height - 1 - f.corner_px[i].y);
    }
    plot_points(s.out + ".cam" + std::to_string(cam) + "-residuals.png", {low, mid, high}, 0,
                s.lane.frame_width - 1, 0, s.lane.frame_height - 1, 80, 50, s.lane.frame_width,
                s.lane.frame_height);
  }
  save_lane_calibration(s.lane, s.out, r);
  std::printf(
      "# cam%d: RMS %.4f px (%.4f mm), uncertainty median %.3f px worst %.3f px; "
      "written to %s\n",
      cam, f.rms_px, f.rms_mm, f.map.median, f.map.worst, s.out.c_str());
  return r.passed ? 0 : 2;
}

int solve_staircase(int argc, char** argv, bool validate) {
  const Args a(argc, argv, 3, {}, {"config", "lane", "calibration", "out"});
  a.expect_positionals(1, validate ? "calib validate SCAN --calibration FILE"
                                   : "calib staircase SCAN [--calibration FILE] [--out FILE]");
  const RecordingReader rec(a.positional(0, "scan folder"));
  const int lane = rec.info().lanes.at(0);
  Session s = open_session(a, lane);
  const fs::path dir = rec.dir();
  int status = 0;
  if (fs::exists(dir / "staircase.yaml")) {
    const Staircase st = parse_staircase(read_drawing(dir / "staircase.yaml"), "staircase.yaml");
    std::printf("# staircase, lane %d: %s\n", lane,
                validate ? "measured with the calibration" : "solving both cameras");
    std::printf("# %-8s %10s %10s %10s   %10s %10s %10s\n", "depth", "cam0 mean", "std", "error",
                "cam1 mean", "std", "error");
    StaircaseFit fits[2];
    for (int cam = 0; cam < 2; ++cam) {
      const auto rows = stripe_rows(rec, lane, cam, s.lane.stripe);
      fits[cam] =
          fit_staircase(rows.data(), rec.info().lines, rec.info().width, s.lane.cameras[cam].model,
                        st, "cam" + std::to_string(cam), !validate);
    }
    for (size_t k = 0; k < st.heights_mm.size(); ++k)
      std::printf("  %-8g %10.3f %10.4f %+10.4f   %10.3f %10.4f %+10.4f\n", st.heights_mm[k],
                  fits[0].steps[k].mean_mm, fits[0].steps[k].std_mm, fits[0].steps[k].error_mm,
                  fits[1].steps[k].mean_mm, fits[1].steps[k].std_mm, fits[1].steps[k].error_mm);
    // Table 5 as a plot: each step's error (mm, +-0.3 full scale) for cam0 (red) and cam1
    // (blue), beside the drawing's height.
    {
      Series c0{{}, {}, 210, 30, 30}, c1{{}, {}, 30, 60, 210};
      for (size_t k = 0; k < st.heights_mm.size(); ++k) {
        c0.x.push_back(st.heights_mm[k] - 0.6), c0.y.push_back(fits[0].steps[k].error_mm);
        c1.x.push_back(st.heights_mm[k] + 0.6), c1.y.push_back(fits[1].steps[k].error_mm);
      }
      const std::string png = (validate ? dir.string() + "/validate" : s.out) + "-steps.png";
      plot_points(png, {c0, c1}, 0, st.heights_mm.back() + 5, -0.3, 0.3, 5, 0.1, 480, 240);
    }
    for (int cam = 0; cam < 2; ++cam) {
      const SolveReport r =
          fits[cam].report("lane " + std::to_string(lane) + " cam" + std::to_string(cam));
      std::printf("# cam%d worst step error %.4f mm%s\n", cam, fits[cam].worst_step_error_mm,
                  r.passed ? "" : "  FAILED");
      if (!r.passed) status = 2;
      if (validate) continue;
      print_report(r);
      s.lane.cameras[cam].model = fits[cam].camera;
      s.lane.laser = LaserPlane{};  // the plane defines the frame: y = 0
      save_lane_calibration(s.lane, s.out, r);
    }
    if (!validate) std::printf("# written to %s\n", s.out.c_str());
  }
  if (validate && fs::exists(dir / "blocks.yaml")) {
    // The calibration as it stands: its cameras and its registration (the stripe's
    // erosion at the blocks' ends is measured on this scan).
    RegistrationOptions hold;
    hold.fit_offset = false, hold.solve_planes = false;
    const FanBeam& x = s.lane.xray;
    hold.delay_lines = x.measured_delay_lines != 0 ? x.measured_delay_lines : x.delay_lines;
    hold.alpha_deg = x.plane_alpha_deg, hold.beta_deg = x.plane_beta_deg;
    const RegistrationFit f = measure_registration(rec, lane, s.lane, hold);
    std::printf(
        "# blocks, lane %d: %d corners, laser vs X-ray %.3f mm mean (along %.3f, across "
        "%.3f), worst %.3f mm\n",
        lane, f.corners, f.corner_mean_mm, f.along_mean_mm, f.across_mean_mm, f.corner_worst_mm);
    const SolveReport r = f.report("lane " + std::to_string(lane) + " validate");
    for (const auto& e : r.failures) std::fprintf(stderr, "FAILED: %s\n", e.c_str());
    if (!r.passed) status = 2;
  } else if (validate && !fs::exists(dir / "staircase.yaml")) {
    fail(dir.string(), ": no staircase.yaml or blocks.yaml: validate needs a known object");
  }
  return status;
}

int solve_xray(int argc, char** argv) {
  const Args a(argc, argv, 3, {"hold-pitch", "row-offsets", "no-tilt"},
               {"config", "lane", "calibration", "out", "pins"});
  Session s = open_session(a, int(a.integer("lane", 0)));
  FanBeamSolveOptions opt;
  opt.start = s.lane.xray;
  opt.fit_pitch = !a.flag("hold-pitch");
  opt.fit_tilt = !a.flag("no-tilt");
  opt.row_offsets = a.flag("row-offsets");
  std::vector<PinObservation> pins;
  std::vector<PinShadow> shadows;
  if (a.has("pins")) {
    // Measured pin positions (e.g. tests/data/table9_pins.csv): x_mm,z_mm,pixel.
    std::ifstream in(a.require("pins"));
    if (!in) fail(a.require("pins"), ": cannot open");
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
      ++n;
      if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
      PinObservation o;
      char c1 = 0, c2 = 0;
      std::istringstream ss(line);
      if (!(ss >> o.x_mm >> c1 >> o.z_mm >> c2 >> o.pixel) || c1 != ',' || c2 != ',')
        fail(a.require("pins"), ":", n, ": expected x_mm,z_mm,pixel");
      o.name = join(a.require("pins"), ":", n);
      pins.push_back(o);
    }
  } else {
    a.expect_positionals(1, "calib xray SCAN | --pins CSV [--hold-pitch] [--row-offsets]");
    const RecordingReader rec(a.positional(0, "scan folder"));
    const PinPhantom ph = parse_pin_phantom(read_drawing(fs::path(rec.dir()) / "pin_phantom.yaml"),
                                            "pin_phantom.yaml");
    const auto x = xray_lines(rec, rec.info().lanes.at(0));
    shadows =
        measure_pin_shadows(x.data(), rec.info().lines, rec.info().xray_pixels, ph, s.lane.xray);
    for (const auto& sh : shadows) pins.push_back(sh.at);
  }
  const FanBeamFit f = fit_fan_beam(pins, opt);
  const SolveReport r = f.report("lane " + std::to_string(s.lane.id) + " xray");
  print_report(r);
  std::printf("# fan beam: %zu pins, residual RMS %.4f px (%.4f mm), worst %.4f px (%s)\n",
              pins.size(), f.rms_px, f.rms_mm, f.worst_px, f.worst_pin.c_str());
  // Pin residuals along the detector (px, +-4 RMS full scale), one colour per row.
  {
    std::vector<Series> rows;
    std::vector<double> heights;
    for (size_t i = 0; i < pins.size(); ++i) {
      const auto it = std::find(heights.begin(), heights.end(), pins[i].z_mm);
      const size_t k = size_t(it - heights.begin());
      if (it == heights.end()) {
        heights.push_back(pins[i].z_mm);
        rows.push_back({{},
                        {},
                        (unsigned char)(40 + 50 * (k % 4)),
                        (unsigned char)(30 * (k % 7)),
                        (unsigned char)(220 - 25 * (k % 8))});
      }
      rows[k].x.push_back(pins[i].pixel);
      rows[k].y.push_back(f.residual_px[i]);
    }
    const double span = std::max(4 * f.rms_px, 1e-3);
    if (!a.has("pins") || a.has("out"))
      plot_points(s.out + ".xray-pins.png", rows, 0, s.lane.xray.pixels - 1, -span, span, 40, 0,
                  640, 240);
  }
  FanBeam fb = f.beam;
  if (!shadows.empty()) {
    const XrayBlurFit b = fit_xray_blur(shadows, f.beam);
    print_report(b.report("lane " + std::to_string(s.lane.id) + " xray"));
    fb.detector_sigma_px = b.detector_sigma_px;
    fb.focal_spot_sigma_mm = b.focal_spot_sigma_mm;
    std::printf("# blur: detector %.3f px, focal spot %.3f mm\n", b.detector_sigma_px,
                b.focal_spot_sigma_mm);
  }
  if (!a.has("pins") || a.has("out")) {
    s.lane.xray = fb;
    save_lane_calibration(s.lane, s.out, r);
    std::printf("# written to %s\n", s.out.c_str());
  }
  return r.passed ? 0 : 2;
}

int solve_registration(int argc, char** argv) {
  const Args a(argc, argv, 3, {}, {"config", "lane", "calibration", "out"});
  a.expect_positionals(1, "calib registration SCAN [--calibration FILE] [--out FILE]");
  const RecordingReader rec(a.positional(0, "scan folder"));
  const int lane = rec.info().lanes.at(0);
  Session s = open_session(a, lane);
  const RegistrationFit f = measure_registration(rec, lane, s.lane, {});
  const SolveReport r = f.report("lane " + std::to_string(lane));
  print_report(r);
  s.lane.cameras[0].model = f.cameras[0];
  s.lane.cameras[1].model = f.cameras[1];
  s.lane.xray.delay_lines = int(std::lround(f.delay_lines));
  s.lane.xray.measured_delay_lines = f.delay_lines;
  s.lane.xray.plane_alpha_deg = f.alpha_deg;
  s.lane.xray.plane_beta_deg = f.beta_deg;
  save_lane_calibration(s.lane, s.out, r);
  std::printf(
      "# delay %.3f lines (%d used), alpha %.3f deg, beta %.3f deg; cameras moved %.3f mm "
      "across the belt into the X-ray's frame; block corners laser vs X-ray %.3f mm mean, "
      "%.3f mm worst; written to %s\n",
      f.delay_lines, s.lane.xray.delay_lines, f.alpha_deg, f.beta_deg, f.offset_mm,
      f.corner_mean_mm, f.corner_worst_mm, s.out.c_str());
  return r.passed ? 0 : 2;
}

}  // namespace

int cmd_calib_simulate(int argc, char** argv);

int cmd_calib_solve(int argc, char** argv) {
  const std::string verb = argv[2];
  if (verb == "simulate") return cmd_calib_simulate(argc, argv);
  if (verb == "camera") return solve_camera(argc, argv);
  if (verb == "staircase") return solve_staircase(argc, argv, false);
  if (verb == "validate") return solve_staircase(argc, argv, true);
  if (verb == "xray") return solve_xray(argc, argv);
  if (verb == "registration") return solve_registration(argc, argv);
  return -1;
}

}  // namespace rangex::cli
