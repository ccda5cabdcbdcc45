// calib simulate targets|staircase|pins|blocks|dual-energy OUT: calibration scans of one lane from
// the simulator, through the plant's rig or (--rig-seed) a rig that differs from it as a real one
// would; the truth (rig, optics, target corners) in OUT/truth or the recording's truth/.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "args.h"
#include "calib/wedge_scan_file.h"
#include "commands.h"
#include "core/error.h"
#include "core/png_io.h"
#include "progress_bar.h"
#include "sim/calib_scenes.h"
#include "sim/dual_energy_phantom.h"
#include "sim/perturbed_rig.h"
#include "sim/plant_physics.h"
#include "sim/target_scene.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p);
  out << text;
  if (!out) fail(p.string(), ": write failed");
}

}  // namespace

int cmd_calib_simulate(int argc, char** argv) {
  const Args a(argc, argv, 3, {},
               {"config", "lane", "rig-seed", "cam", "views", "seed", "physics", "step-lines"});
  a.expect_positionals(
      2, "calib simulate targets|staircase|pins|blocks|dual-energy OUT [--rig-seed S]");
  const std::string kind = a.positional(0, "scene"), out = a.positional(1, "output folder");
  const PlantConfig plant = load_config(a.get("config", ""));
  const LaneConfig& nominal = plant.lane(int(a.integer("lane", 0)));
  sim::SimulatedRig rig;
  if (a.has("rig-seed")) {
    rig = sim::perturbed_rig(nominal, (unsigned long)a.integer("rig-seed", 1));
  } else {
    rig.lane = nominal;
    rig.xray_plane_y_mm =
        nominal.laser.offset_mm + nominal.xray.delay_lines * nominal.encoder_step_mm;
    rig.alpha_rad = rig.beta_rad = 0;
  }
  // A plant with other X-ray physics (config/variants/*.yaml): its detector blur, focal spot
  // and plane geometry against the laser's.
  if (a.has("physics")) {
    const sim::XrayPhysics x = sim::load_plant_physics(a.require("physics")).xray;
    const LaneConfig& l = rig.lane;
    rig.xray_plane_y_mm =
        l.laser.offset_mm + (l.xray.delay_lines + x.plane_offset_lines) * l.encoder_step_mm;
    rig.alpha_rad = x.alpha_deg * M_PI / 180;
    rig.beta_rad = x.beta_deg * M_PI / 180;
    rig.detector_sigma_px = x.detector_sigma_px;
    rig.focal_spot_sigma_mm = x.focal_spot_sigma_mm;
  }
  const uint64_t seed = uint64_t(a.integer("seed", 1));
  if (kind == "dual-energy") {
    // The step wedge of A-150 and aluminium through the lane's sandwich detector.
    const LaneConfig& l = rig.lane;
    if (l.xray.energies != 2)
      fail("calib simulate dual-energy: lane ", l.id,
           " has one X-ray energy (set xray.energies: 2 and its sandwich in plant.yaml)");
    WedgeLayout w;
    w.step_lines = int(a.integer("step-lines", w.step_lines));
    if (w.step_lines < 2 * w.margin_lines + 2)
      fail("--step-lines must be at least ", 2 * w.margin_lines + 2);
    const sim::DualEnergyRenderer detector(l.xray.sandwich);
    std::vector<uint16_t> low, high;
    sim::render_wedge_lines(detector, l.xray, w, seed, low, high);
    write_wedge_scan(out, w, l.xray.pixels, low, high);
    std::printf("dual-energy wedge scan of lane %d in %s: %d lines, %zu steps\n", l.id, out.c_str(),
                w.lines(), w.a150_mm.size() * w.al_mm.size());
    return 0;
  }
  if (kind == "targets") {
    const int cam = int(a.integer("cam", 0));
    if (cam < 0 || cam > 1) fail("--cam must be 0 or 1");
    const CameraModel& model = rig.lane.cameras[cam].model;
    const sim::TargetBoard board;
    const sim::TargetRenderer renderer(model, board);
    const auto poses = sim::random_target_poses(model, board, int(a.integer("views", 60)), seed);
    fs::create_directories(fs::path(out) / "truth");
    std::ofstream corners(fs::path(out) / "truth" / "corners.csv");
    corners << "image,corner,u,v\n";
    std::vector<uint8_t> frame(size_t(model.width()) * model.height());
    ProgressBar bar("target images");
    for (size_t k = 0; k < poses.size(); ++k) {
      sim::Rng rng(seed, k, 0x7a);
      std::vector<Vec2> truth;
      renderer.render(poses[k], rng, frame.data(), &truth);
      char name[32];
      std::snprintf(name, sizeof name, "target_%03zu.png", k);
      write_png8((fs::path(out) / name).string(), frame.data(), model.width(), model.height());
      for (size_t i = 0; i < truth.size(); ++i)
        corners << name << "," << i << "," << truth[i].x << "," << truth[i].y << "\n";
      bar.update(int64_t(k + 1), int64_t(poses.size()));
    }
    write_text(fs::path(out) / "board.yaml",
               join("board: {cols: ", board.cols, ", rows: ", board.rows,
                    ", square_mm: ", board.square_mm, "}\ncamera: ", cam, "\n"));
    write_text(fs::path(out) / "truth" / "rig.yaml", lane_calibration_yaml(rig.lane));
    std::printf("%zu target images of cam%d in %s\n", poses.size(), cam, out.c_str());
    return 0;
  }
  sim::CalibScene scene;
  std::string drawing, name;
  sim::CalibScanParams p;
  p.seed = seed;
  p.optics.plane_y_mm = rig.xray_plane_y_mm;
  p.optics.alpha_rad = rig.alpha_rad;
  p.optics.beta_rad = rig.beta_rad;
  p.optics.detector_sigma_px = rig.detector_sigma_px;
  p.optics.focal_spot_sigma_mm = rig.focal_spot_sigma_mm;
  if (kind == "staircase") {
    const Staircase s;
    Staircase placed = s;
    placed.x0_mm += rig.staircase_offset_mm;
    scene = sim::staircase_scene(placed);
    drawing = to_yaml(s), name = "staircase.yaml";
  } else if (kind == "pins") {
    const PinPhantom ph = PinPhantom::figure27();
    scene = sim::pin_phantom_scene(ph);
    drawing = to_yaml(ph), name = "pin_phantom.yaml";
    p.cameras = false;
  } else if (kind == "blocks") {
    const BlockSet b = BlockSet::standard();
    scene = sim::block_scene(b, seed);
    drawing = to_yaml(b), name = "blocks.yaml";
  } else {
    fail("calib simulate: unknown scene '", kind,
         "' (targets, staircase, pins, blocks, dual-energy)");
  }
  ProgressBar bar(kind + " scan");
  sim::simulate_calib_scan(rig.lane, scene, p, out,
                           [&](int64_t d, int64_t t) { bar.update(d, t); });
  write_text(fs::path(out) / name, drawing);
  if (kind == "staircase")
    write_text(fs::path(out) / ("lane" + std::to_string(rig.lane.id)) / "truth" / "placement.yaml",
               join("staircase_offset_mm: ", rig.staircase_offset_mm, "\n"));
  std::printf("%s scan of lane %d in %s (drawing: %s)\n", kind.c_str(), rig.lane.id, out.c_str(),
              name.c_str());
  return 0;
}

}  // namespace rangex::cli
