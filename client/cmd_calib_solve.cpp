// calib camera|staircase|xray|registration|validate|dual-energy: the integrator's solves. Each
// reads the lane's current calibration (--calibration FILE, else the plant's lane), solves one part
// from a scan (server/calib), prints the report and writes the updated calibration to
// --out with its report beside it (FILE.reports/).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "args.h"
#include "calib/camera_images_solve.h"
#include "calib/dual_energy_fit.h"
#include "calib/lane_calibration_file.h"
#include "calib/pin_phantom_solve.h"
#include "calib/staircase_scan_solve.h"
#include "calib/wedge_scan_file.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

void print_report(const SolveReport& r) {
  std::printf("%s", reports_json({r}).c_str());
  for (const auto& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!r.passed)
    for (const auto& f : r.failures) std::fprintf(stderr, "FAILED: %s\n", f.c_str());
}

void print_line(const std::string& l) {
  std::fprintf(stderr, "%s\n", l.c_str());
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

// --fix k3,p1,p2,skew: parameters held (distortion terms at 0, skew at 0).
void parse_fixed(const std::string& list_text, CameraSolveOptions& opt) {
  std::stringstream list(list_text);
  std::string name;
  while (std::getline(list, name, ',')) {
    const auto& names = CameraFit::kNames;
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end() || it - names.begin() < 4)
      fail("--fix: '", name, "' is not a parameter that can be held (skew, k1, k2, p1, p2, k3)");
    opt.fixed[size_t(it - names.begin())] = true;
  }
}

int solve_camera(int argc, char** argv) {
  const Args a(argc, argv, 3, {"skip-unfound"},
               {"config", "lane", "cam", "calibration", "out", "fix"});
  a.expect_positionals(
      1, "calib camera DIR [--cam N] [--fix PARAMS] [--calibration FILE] [--out FILE]");
  const std::string dir = a.positional(0, "image folder");
  CameraImagesOptions opt;
  opt.cam = int(a.integer("cam", read_target_board(dir).camera.value_or(0)));
  if (opt.cam < 0 || opt.cam > 1) fail("--cam must be 0 or 1");
  opt.skip_unfound = a.flag("skip-unfound");
  parse_fixed(a.get("fix", ""), opt.solve);
  opt.solve.progress = print_line;
  opt.warn = [](const std::string& w) { print_line("warning: " + w); };
  Session s = open_session(a, int(a.integer("lane", 0)));
  const CameraImagesSolve r = solve_camera_from_images(dir, s.lane, opt, s.out);
  std::printf("# %zu of %zu images with the target; solved cam%d\n", r.with_target, r.images,
              opt.cam);
  print_report(r.report);
  save_lane_calibration(s.lane, s.out, r.report);
  const CameraFit& f = r.fit;
  std::printf(
      "# cam%d: RMS %.4f px (%.4f mm), uncertainty median %.3f px worst %.3f px; "
      "written to %s\n",
      opt.cam, f.rms_px, f.rms_mm, f.map.median, f.map.worst, s.out.c_str());
  return r.report.passed ? 0 : 2;
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
    std::printf("# staircase, lane %d: %s\n", lane,
                validate ? "measured with the calibration" : "solving both cameras");
    const std::string png = (validate ? dir.string() + "/validate" : s.out) + "-steps.png";
    const StaircaseScanSolve r = solve_staircase_scan(rec, lane, s.lane, !validate, png);
    std::printf("# %-8s %10s %10s %10s   %10s %10s %10s\n", "depth", "cam0 mean", "std", "error",
                "cam1 mean", "std", "error");
    for (size_t k = 0; k < r.drawing.heights_mm.size(); ++k) {
      const auto &s0 = r.fits[0].steps[k], &s1 = r.fits[1].steps[k];
      std::printf("  %-8g %10.3f %10.4f %+10.4f   %10.3f %10.4f %+10.4f\n", r.drawing.heights_mm[k],
                  s0.mean_mm, s0.std_mm, s0.error_mm, s1.mean_mm, s1.std_mm, s1.error_mm);
    }
    for (int cam = 0; cam < 2; ++cam) {
      std::printf("# cam%d worst step error %.4f mm%s\n", cam, r.fits[cam].worst_step_error_mm,
                  r.reports[cam].passed ? "" : "  FAILED");
      if (!r.reports[cam].passed) status = 2;
      if (validate) continue;
      print_report(r.reports[cam]);
      save_lane_calibration(s.lane, s.out, r.reports[cam]);
    }
    if (!validate) std::printf("# written to %s\n", s.out.c_str());
  }
  if (validate && fs::exists(dir / "blocks.yaml")) {
    const RegistrationFit f = check_blocks_scan(rec, lane, s.lane);
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
    // Measured pin positions (e.g. tests/data/table9_pins.csv).
    pins = read_pin_csv(a.require("pins"));
  } else {
    a.expect_positionals(1, "calib xray SCAN | --pins CSV [--hold-pitch] [--row-offsets]");
    const RecordingReader rec(a.positional(0, "scan folder"));
    shadows = measure_scan_pins(rec, s.lane.xray);
    for (const auto& sh : shadows) pins.push_back(sh.at);
  }
  // Pins from a CSV alone are a check of the solver: nothing is written unless asked.
  const bool write = !a.has("pins") || a.has("out");
  const PinPhantomSolve r = solve_pin_phantom(pins, shadows, opt, s.lane.xray.pixels,
                                              write ? s.out + ".xray-pins.png" : "");
  const FanBeamFit& f = r.fit;
  const SolveReport report = f.report("lane " + std::to_string(s.lane.id) + " xray");
  print_report(report);
  std::printf("# fan beam: %zu pins, residual RMS %.4f px (%.4f mm), worst %.4f px (%s)\n",
              pins.size(), f.rms_px, f.rms_mm, f.worst_px, f.worst_pin.c_str());
  if (r.blur) {
    print_report(r.blur->report("lane " + std::to_string(s.lane.id) + " xray"));
    std::printf("# blur: detector %.3f px, focal spot %.3f mm\n", r.blur->detector_sigma_px,
                r.blur->focal_spot_sigma_mm);
  }
  if (write) {
    s.lane.xray = r.beam;
    save_lane_calibration(s.lane, s.out, report);
    std::printf("# written to %s\n", s.out.c_str());
  }
  return report.passed ? 0 : 2;
}

int solve_registration(int argc, char** argv) {
  const Args a(argc, argv, 3, {}, {"config", "lane", "calibration", "out"});
  a.expect_positionals(1, "calib registration SCAN [--calibration FILE] [--out FILE]");
  const RecordingReader rec(a.positional(0, "scan folder"));
  const int lane = rec.info().lanes.at(0);
  Session s = open_session(a, lane);
  const RegistrationFit f = solve_blocks_scan(rec, lane, s.lane);
  const SolveReport r = f.report("lane " + std::to_string(lane));
  print_report(r);
  save_lane_calibration(s.lane, s.out, r);
  std::printf(
      "# delay %.3f lines (%d used), alpha %.3f deg, beta %.3f deg; cameras moved %.3f mm "
      "across the belt into the X-ray's frame; block corners laser vs X-ray %.3f mm mean, "
      "%.3f mm worst; written to %s\n",
      f.delay_lines, s.lane.xray.delay_lines, f.alpha_deg, f.beta_deg, f.offset_mm,
      f.corner_mean_mm, f.corner_worst_mm, s.out.c_str());
  return r.passed ? 0 : 2;
}

// The dual-energy calibration from a step-wedge scan (calib/dual_energy_fit.h).
int solve_dual_energy(int argc, char** argv) {
  const Args a(argc, argv, 3, {}, {"config", "lane", "calibration", "out", "laser-sigma-mm"});
  a.expect_positionals(1,
                       "calib dual-energy SCAN [--calibration FILE] [--out FILE] "
                       "[--laser-sigma-mm S]");
  const std::string dir = a.positional(0, "wedge scan folder");
  Session s = open_session(a, int(a.integer("lane", 0)));
  FanBeam& x = s.lane.xray;
  if (x.energies != 2)
    fail("calib dual-energy: lane ", s.lane.id,
         " has one X-ray energy (set xray.energies: 2 and its sandwich in plant.yaml)");
  const double laser_sigma = std::stod(a.get("laser-sigma-mm", "0.1"));
  if (!(laser_sigma >= 0 && laser_sigma < 5)) fail("--laser-sigma-mm must be within 0..5 mm");
  const WedgeScan scan = read_wedge_scan(dir, x);
  const DualEnergyFit f = fit_dual_energy(scan, x.sandwich, laser_sigma);
  SolveReport r;
  r.solver = "dual-energy";
  r.subject = "lane " + std::to_string(s.lane.id);
  r.figures = {{"steps", double(f.steps.size())},
               {"a150_rms_mm", f.a_rms},
               {"al_rms_mm", f.b_rms},
               {"a150_worst_percent", 100 * f.a_worst_rel},
               {"al_worst_percent", 100 * f.b_worst_rel}};
  const char* names[3] = {"lean", "fat", "bone"};
  for (int m = 0; m < 3; ++m) {
    r.parameters.push_back({std::string(names[m]) + "_a150", f.params.basis[2 * m], 0, "mm/mm"});
    r.parameters.push_back({std::string(names[m]) + "_al", f.params.basis[2 * m + 1], 0, "mm/mm"});
  }
  // The wedge's own steps taken back through the fit: the bar is 1 %.
  for (auto [what, worst] :
       {std::pair{"A-150", f.a_worst_rel}, std::pair{"aluminium", f.b_worst_rel}})
    if (!(worst <= 0.01)) {
      r.passed = false;
      r.failures.push_back(std::string(what) + " steps recovered within " +
                           std::to_string(100 * worst) + " %, more than 1 %");
    }
  r.warnings.push_back(
      "lean, fat and bone in the basis come from NIST's coefficients through the detector's "
      "nominal spectra, not from this plant's product");
  print_report(r);
  std::printf("%s", dual_energy_report(f).c_str());
  x.dual_energy = f.params;
  x.has_dual_energy = true;
  x.dual_energy_fitted_on = fs::absolute(dir).string();
  save_lane_calibration(s.lane, s.out, r);
  std::printf("# written to %s\n", s.out.c_str());
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
  if (verb == "dual-energy") return solve_dual_energy(argc, argv);
  return -1;
}

}  // namespace rangex::cli
