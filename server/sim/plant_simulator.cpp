#include "sim/plant_simulator.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/recording.h"

namespace rangex::sim {

SceneParams scene_params(const SimulationParams& p) {
  SceneParams s = p.scene;
  const PlantPhysics& ph = p.physics;
  s.close_gap_probability = ph.shapes.touching_probability;
  s.scatter_spread = ph.scatter.spread;
  s.debris_probability = ph.belt.debris_probability;
  s.fat_share_min = ph.meat.fat_share_min, s.fat_share_max = ph.meat.fat_share_max;
  FilletParams& f = s.fillet;
  f.bone_probability = ph.bones.probability;
  f.calcification_min = ph.bones.calcification_min;
  f.calcification_max = ph.bones.calcification_max;
  f.needle = ph.bones.needle, f.chip = ph.bones.chip, f.rib = ph.bones.rib;
  f.cluster = ph.bones.cluster;
  f.cartilage_probability = ph.bones.cartilage_probability;
  f.steep_fraction = ph.shapes.steep_fraction;
  f.flap_probability = ph.shapes.flap_probability;
  f.fold_probability = ph.shapes.fold_probability;
  f.meat = {ph.meat.texture_std, ph.meat.marbling, ph.meat.marbling_contrast};
  return s;
}

CameraRenderParams camera_params(const SimulationParams& p) {
  CameraRenderParams c = p.camera;
  const PlantPhysics& ph = p.physics;
  c.core_sigma_px = ph.laser.core_sigma_px;
  c.defocus_px_per_mm = ph.laser.defocus_px_per_mm;
  c.meat_tail_base = ph.scatter.tail_base;
  c.meat_tail_gain = ph.scatter.tail_gain;
  c.meat_tail_px = ph.scatter.tail_px;
  c.tail_direction = ph.scatter.direction;
  c.speckle = ph.speckle.pixel;
  c.column_speckle = ph.speckle.column;
  c.speckle_correlation_px = ph.speckle.correlation_px;
  c.glint_probability = ph.speckle.glint_probability;
  c.belt_texture = ph.belt.texture;
  return c;
}

LaneSimulator::LaneSimulator(const LaneConfig& lane, const SimulationParams& p)
    : lane_(lane),
      seed_(p.seed),
      scene_(p.seed, lane.id, scene_params(p)),
      cam0_(lane, 0, camera_params(p)),
      cam1_(lane, 1, camera_params(p)),
      xray_(lane, p.xray, p.physics.xray),
      encoder_start_(p.encoder_start),
      dropped_rate_(p.physics.belt.dropped_line_rate),
      jitter_mm_(p.physics.belt.encoder_jitter_mm) {
  const double xray_y = std::max(xray_.plane_y(-110, 0), xray_.plane_y(110, 60));
  lines_ = int64_t(std::ceil((scene_.end_b() + std::max(0.0, xray_y) + 20) / lane.encoder_step_mm));
}

bool LaneSimulator::dropped(int64_t n) const {
  if (dropped_rate_ <= 0) return false;
  Rng r(seed_, uint64_t(lane_.id), uint64_t(n), 0xd409);
  return r.chance(dropped_rate_);
}

void LaneSimulator::render(int64_t n, uint8_t* cam0, uint8_t* cam1, uint16_t* xray,
                           float* truth_row0, float* truth_row1, float* truth_thickness,
                           uint16_t* xray_high) const {
  const double s = double(n) * lane_.encoder_step_mm;
  std::vector<float> scratch_rows(lane_.frame_width), scratch_t(lane_.xray.pixels);
  Rng r0(seed_, uint64_t(lane_.id) * 3 + 0, uint64_t(n), 0xc0);
  Rng r1(seed_, uint64_t(lane_.id) * 3 + 1, uint64_t(n), 0xc1);
  Rng rx(seed_, uint64_t(lane_.id) * 3 + 2, uint64_t(n), 0x7a);
  // Encoder jitter: the cameras (triggered together) and the X-ray each take their line a
  // little off the count's position.
  double s_cam = s, s_xray = s;
  if (jitter_mm_ > 0) {
    Rng rj(seed_, uint64_t(lane_.id), uint64_t(n), 0x717);
    s_cam += jitter_mm_ * rj.normal();
    s_xray += jitter_mm_ * rj.normal();
  }
  cam0_.render(scene_, s_cam, r0, cam0, truth_row0 ? truth_row0 : scratch_rows.data());
  cam1_.render(scene_, s_cam, r1, cam1, truth_row1 ? truth_row1 : scratch_rows.data());
  if (dropped(n)) {
    // Both cameras' frames of this line lost on the way (black); the X-ray line arrives.
    const size_t frame = size_t(lane_.frame_width) * lane_.frame_height;
    std::fill(cam0, cam0 + frame, uint8_t(0));
    std::fill(cam1, cam1 + frame, uint8_t(0));
  }
  xray_.render(scene_, s_xray, rx, xray, truth_thickness ? truth_thickness : scratch_t.data(),
               xray_high);
}

std::string LaneSimulator::fragments_csv() const {
  std::ostringstream os;
  // excess_mu: its attenuation over the meat's, meat_mu: the meat's (1/mm): what a
  // sensitivity claim's bone-equivalent test piece is weighed against.
  os << "fillet,kind,x_mm,b_mm,z_mm,xray_line,size_mm,calcification,shape,volume_mm3,excess_mu,"
        "meat_mu\n";
  static const char* kKind[] = {"bone", "air", "fat", "cartilage"};
  static const char* kShape[] = {"compact", "needle", "chip", "rib", "cluster"};
  for (const Fillet& f : scene_.fillets())
    for (size_t k = 0; k < f.inclusions.size(); ++k) {
      const Inclusion& in = f.inclusions[k];
      if (in.kind == Inclusion::kFat || in.secondary) continue;
      // A fragment of several parts (rib, cluster) is where its parts' volume is centred.
      Vec3 c = in.center * (in.semi.x * in.semi.y * in.semi.z);
      double v = in.semi.x * in.semi.y * in.semi.z;
      for (size_t j = k + 1; j < f.inclusions.size() && f.inclusions[j].secondary; ++j) {
        const Inclusion& p = f.inclusions[j];
        c = c + p.center * (p.semi.x * p.semi.y * p.semi.z);
        v += p.semi.x * p.semi.y * p.semi.z;
      }
      c = c * (1 / v);
      // The X-ray sees b = line * step - plane_y(x, z).
      const double line = (c.y + xray_.plane_y(c.x, c.z)) / lane_.encoder_step_mm;
      os << f.id << "," << kKind[in.kind] << "," << c.x << "," << c.y << "," << c.z << "," << line
         << "," << in.size_mm << "," << in.calcification << "," << kShape[in.shape] << ","
         << 4.0 / 3.0 * M_PI * v << "," << in.dmu << "," << f.mu << "\n";
    }
  return os.str();
}

std::string LaneSimulator::fillets_csv() const {
  std::ostringstream os;
  os << "fillet,x_center_mm,b_start_mm,b_end_mm,max_height_mm,bones\n";
  for (const Fillet& f : scene_.fillets()) {
    if (f.debris) continue;
    float hmax = 0;
    for (float h : f.height) hmax = std::max(hmax, h);
    int bones = 0;
    for (const Inclusion& in : f.inclusions) bones += in.kind == Inclusion::kBone;
    os << f.id << "," << f.x_center << "," << f.b_start << "," << f.b_max << "," << hmax << ","
       << bones << "\n";
  }
  return os.str();
}

void simulate_recording(const PlantConfig& plant, const SimulationParams& p, const std::string& dir,
                        const Progress& progress) {
  if (p.lanes <= 0 || p.lanes > int(plant.lanes.size()))
    fail("cannot simulate ", p.lanes, " lanes: the plant configuration has ", plant.lanes.size());
  if (p.scene.fillets <= 0)
    fail("number of fillets per lane must be > 0 (got ", p.scene.fillets, ")");
  std::vector<LaneSimulator> sims;
  RecordingInfo info;
  const LaneConfig& first = plant.lanes.front();
  for (int i = 0; i < p.lanes; ++i) {
    const LaneConfig& l = plant.lanes[i];
    if (l.frame_width != first.frame_width || l.frame_height != first.frame_height ||
        l.xray.pixels != first.xray.pixels || l.encoder_step_mm != first.encoder_step_mm ||
        l.xray.energies != first.xray.energies)
      fail("lane ", l.id,
           ": a recording needs equal frame sizes, detector pixels, X-ray energies and encoder "
           "step on every lane");
    sims.emplace_back(l, p);
    info.lanes.push_back(l.id);
  }
  int64_t lines = 0;
  for (const auto& s : sims) lines = std::max(lines, s.lines());
  info.width = first.frame_width;
  info.height = first.frame_height;
  info.xray_pixels = first.xray.pixels;
  info.xray_energies = first.xray.energies;
  info.encoder_step_mm = first.encoder_step_mm;
  info.calibration_id = plant.calibration_id;
  info.has_truth = true;
  info.seed = p.seed;
  RecordingWriter writer(dir, info);

  const int W = info.width, H = info.height, D = info.xray_pixels;
  const size_t frame = size_t(W) * H;
  constexpr int kBlock = 32;  // lines rendered in parallel before they are written in order
  const unsigned workers = std::max(1u, std::thread::hardware_concurrency());
  std::vector<uint8_t> cam0(frame * kBlock), cam1(frame * kBlock);
  std::vector<uint16_t> xray(size_t(D) * kBlock), high(info.xray_energies == 2 ? xray.size() : 0);
  const bool dual = !high.empty();
  std::vector<float> row0(size_t(W) * kBlock), row1(size_t(W) * kBlock), thick(size_t(D) * kBlock);
  const int64_t total = lines * int64_t(sims.size());
  int64_t done = 0;
  for (size_t li = 0; li < sims.size(); ++li) {
    const LaneSimulator& sim = sims[li];
    for (int64_t n0 = 0; n0 < lines; n0 += kBlock) {
      const int count = int(std::min<int64_t>(kBlock, lines - n0));
      std::vector<std::thread> pool;
      for (unsigned w = 0; w < workers; ++w)
        pool.emplace_back([&, w] {
          for (int k = int(w); k < count; k += int(workers))
            sim.render(n0 + k, &cam0[frame * k], &cam1[frame * k], &xray[size_t(D) * k],
                       &row0[size_t(W) * k], &row1[size_t(W) * k], &thick[size_t(D) * k],
                       dual ? &high[size_t(D) * k] : nullptr);
        });
      for (auto& t : pool) t.join();
      for (int k = 0; k < count; ++k)
        writer.append(info.lanes[li], {&cam0[frame * k], &cam1[frame * k], &xray[size_t(D) * k],
                                       sim.encoder(n0 + k), dual ? &high[size_t(D) * k] : nullptr});
      writer.append_truth(info.lanes[li], "stripe_cam0.f32", row0.data(), size_t(W) * count * 4);
      writer.append_truth(info.lanes[li], "stripe_cam1.f32", row1.data(), size_t(W) * count * 4);
      writer.append_truth(info.lanes[li], "thickness.f32", thick.data(), size_t(D) * count * 4);
      done += count;
      if (progress) progress(done, total);
    }
    writer.write_truth_text(info.lanes[li], "fragments.csv", sim.fragments_csv());
    writer.write_truth_text(info.lanes[li], "fillets.csv", sim.fillets_csv());
    writer.write_truth_text(info.lanes[li], "physics.yaml", to_yaml(p.physics));
  }
  writer.close();
}

}  // namespace rangex::sim
