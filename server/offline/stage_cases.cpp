#include "offline/stage_cases.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include "backends/verify.h"
#include "sim/plant_simulator.h"

namespace rangex {

namespace {

// Equal within abs + rel * |want|; NaN equals NaN only.
bool within(double got, double want, double abs_tol, double rel_tol) {
  if (std::isnan(got) || std::isnan(want)) return std::isnan(got) && std::isnan(want);
  return std::fabs(got - want) <= abs_tol + rel_tol * std::fabs(want);
}

template <class A, class B>
std::string first_difference(const char* name, const A& got, const B& want, size_t n,
                             double abs_tol, double rel_tol) {
  if (got.size() < n || want.size() < n) return std::string(name) + ": too few items";
  for (size_t i = 0; i < n; ++i)
    if (!within(double(got[i]), double(want[i]), abs_tol, rel_tol)) {
      std::ostringstream s;
      s.precision(9);
      s << name << " item " << i << ": " << double(got[i]) << ", the reference " << double(want[i]);
      return s.str();
    }
  return "";
}

// The lanes of a batch: each with other settings and calibrations than the last.
std::vector<LaneConfig> varied_lanes(const LaneConfig& base, int lanes) {
  std::vector<LaneConfig> v;
  const StripeMethod methods[] = {base.stripe.method, StripeMethod::kGaussian3,
                                  StripeMethod::kBinary, StripeMethod::kCentroid};
  for (int i = 0; i < lanes; ++i) {
    LaneConfig l = base;
    l.id = i;
    l.stripe.method = methods[i % 4];
    l.laser.offset_mm = 0.1 * (i % 5);
    l.xray.source_x_mm += 0.5 * (i % 3);
    v.push_back(l);
  }
  return v;
}

}  // namespace

FilletBatch StageWork::fillets() const {
  return {fillet_thickness.data(), fillet_xray.data(),        fillet_use.data(),
          fillet_offsets.data(),   int(fillet_models.size()), fillet_models.data()};
}

DualEnergyBoneBatch StageWork::de_bone() const {
  DualEnergyBoneBatch b;
  b.basis = de_basis.data(), b.thickness = de_rays.thickness.data();
  b.phi = de_phi.data(), b.phi_var = de_phi_var.data();
  b.pixels = de_rays.pixels();
  b.density_var = 0.03 * 0.03;
  return b;
}

std::vector<uint8_t> render_distinct_lines(const LaneConfig& lane, int count) {
  sim::SimulationParams sp;
  sp.scene.fillets = 2;
  sp.scene.lead_in_mm = 5;
  const sim::LaneSimulator sim(lane, sp);
  const size_t frame = size_t(lane.frame_width) * lane.frame_height;
  std::vector<uint8_t> rendered(2 * frame * size_t(count));
  std::vector<uint16_t> xray(size_t(lane.xray.pixels));
  for (int k = 0; k < count; ++k)
    sim.render(int64_t(k) * std::max<int64_t>(1, sim.lines() / count), &rendered[2 * frame * k],
               &rendered[2 * frame * k + frame], xray.data(), nullptr, nullptr, nullptr);
  return rendered;
}

LineBatchInputs interleave_lines(const std::vector<uint8_t>& rendered, size_t frame, int lanes,
                                 int lines) {
  LineBatchInputs b;
  b.lanes = lanes;
  b.lines = lines;
  b.frame = frame;
  const size_t distinct = rendered.size() / (2 * frame);
  b.frames.resize(size_t(lines) * 2 * frame);
  for (int k = 0; k < lines; ++k) {
    std::memcpy(&b.frames[2 * frame * k], &rendered[2 * frame * (k % distinct)], 2 * frame);
    b.lane_slot.push_back(k % lanes);
    b.frame_slot.push_back(2 * (k % lanes));
    b.frame_slot.push_back(2 * (k % lanes) + 1);
  }
  return b;
}

StageWork make_stage_work(const LaneConfig& lane, int lanes, int lines, int fillets,
                          int fillet_pixels, int dual_energy_pixels) {
  StageWork w;
  w.lanes = varied_lanes(lane, lanes);
  const size_t frame = size_t(lane.frame_width) * lane.frame_height;
  // Up to 64 distinct lines of a simulated lane with fillets in it.
  w.batch = interleave_lines(render_distinct_lines(lane, std::min(lines, 64)), frame, lanes, lines);
  const LinePipeline pipe(w.lanes, 1);
  pipe.run(w.batch.frames.data(), lines, w.batch.lane_slot.data(), w.ref);
  // Fillets whose attenuation follows a known model, with a little noise.
  w.fillet_offsets.assign(size_t(fillets) + 1, 0);
  for (int f = 0; f < fillets; ++f) {
    w.fillet_offsets[f + 1] = w.fillet_offsets[f] + fillet_pixels;
    w.fillet_models.push_back({std::log(3600.0), -0.03, 0.02, 5.0, 4.0, 800.0});
    for (int i = 0; i < fillet_pixels; ++i) {
      const float t = float(30.0 * ((i * 7919) % fillet_pixels) / fillet_pixels);
      w.fillet_thickness.push_back(t);
      w.fillet_xray.push_back(uint16_t(3600.0 * std::exp(-0.03 * t) * (1 + 0.01 * ((i % 13) - 6))));
      w.fillet_use.push_back(i % 17 != 0);
    }
  }
  // Dual energy: rays of every mix, the CPU's basis of them, a fat share that varies.
  const DualEnergyCalibrated c = calibrate_dual_energy(20000);
  w.de_params = c.params;
  w.de_rays = mixed_dual_energy_rays(c, dual_energy_pixels, 5);
  const size_t n = size_t(dual_energy_pixels);
  w.de_basis.resize(5 * n);
  dual_energy_basis(w.de_rays.batch(), w.de_params, w.de_basis.data());
  for (size_t i = 0; i < n; ++i) {
    w.de_phi.push_back(float(0.02 + 0.2 * double(i % 101) / 100));
    w.de_phi_var.push_back(float(1e-4 * double(1 + i % 7)));
  }
  return w;
}

namespace {

// The line stages: stripes, rectification, fusion, projection.
void add_line_cases(const StageWork& w, std::vector<StageCase>& cases) {
  const int lines = w.batch.lines, frames = 2 * lines;
  const int width = w.lanes.front().frame_width;
  const size_t cols = size_t(frames) * size_t(width);
  const size_t grid = w.ref.profile.size(), pixels = w.ref.thickness.size();
  cases.push_back({"stripe", "flags exact, rows within 1e-4 px", double(cols), "columns",
                   [frames](Backend& b, const StageWork& w, StageOutput& o) {
                     b.stripes(w.batch.frames.data(), frames, w.batch.frame_slot.data(), o.stripes);
                   },
                   [cols](const StageOutput& g, const StageOutput& r) {
                     std::string d = first_difference("stripe valid", g.stripes.valid,
                                                      r.stripes.valid, cols, 0, 0);
                     if (d.empty())
                       d = first_difference("stripe row", g.stripes.row, r.stripes.row, cols,
                                            Tolerance::kRowPx, 0);
                     return d;
                   }});
  cases.push_back(
      {"rectify", "flags exact, x and z within 1e-4 mm", double(cols), "columns",
       [frames, cols](Backend& b, const StageWork& w, StageOutput& o) {
         o.x.resize(cols), o.z.resize(cols), o.xz_valid.resize(cols);
         b.rectify(w.ref.stripes.row.data(), w.ref.stripes.valid.data(), frames,
                   w.batch.frame_slot.data(), o.x.data(), o.z.data(), o.xz_valid.data());
       },
       [cols](const StageOutput& g, const StageOutput& r) {
         std::string d = first_difference("rectified valid", g.xz_valid, r.xz_valid, cols, 0, 0);
         if (d.empty())
           d = first_difference("rectified x", g.x, r.x, cols, Tolerance::kRectifiedMm, 0);
         if (d.empty())
           d = first_difference("rectified z", g.z, r.z, cols, Tolerance::kRectifiedMm, 0);
         return d;
       }});
  cases.push_back(
      {"fuse", "flags exact, heights within 1e-4 mm", double(lines), "lines",
       [lines, grid](Backend& b, const StageWork& w, StageOutput& o) {
         o.profile.resize(grid), o.profile_valid.resize(grid);
         b.fuse(w.ref.x.data(), w.ref.z.data(), w.ref.xz_valid.data(), lines,
                w.batch.lane_slot.data(), o.profile.data(), o.profile_valid.data(), nullptr);
       },
       [grid](const StageOutput& g, const StageOutput& r) {
         std::string d =
             first_difference("profile valid", g.profile_valid, r.profile_valid, grid, 0, 0);
         if (d.empty())
           d = first_difference("profile", g.profile, r.profile, grid, Tolerance::kProfileMm, 0);
         return d;
       }});
  cases.push_back({"project", "flags exact, thickness within 1e-3 mm", double(lines), "lines",
                   [lines, pixels](Backend& b, const StageWork& w, StageOutput& o) {
                     o.thickness.resize(pixels), o.thickness_valid.resize(pixels);
                     b.project(w.ref.profile.data(), w.ref.profile_valid.data(), lines,
                               w.batch.lane_slot.data(), o.thickness.data(),
                               o.thickness_valid.data());
                   },
                   [pixels](const StageOutput& g, const StageOutput& r) {
                     std::string d = first_difference("thickness valid", g.thickness_valid,
                                                      r.thickness_valid, pixels, 0, 0);
                     if (d.empty())
                       d = first_difference("thickness", g.thickness, r.thickness, pixels,
                                            Tolerance::kThicknessMm, 0);
                     return d;
                   }});
}

// The pseudo-X-ray stages over the batch of fillets.
void add_fillet_cases(const StageWork& w, std::vector<StageCase>& cases) {
  const size_t fillet_px = w.fillet_thickness.size();
  // ln P within float rounding of the double model, P within exp's error (relative),
  // residual and z to float rounding of the same values.
  cases.push_back({"pseudo-xray", "ln P 1e-6, P 1e-5 relative, residual 2e-6, z 1e-5",
                   double(fillet_px), "pixels",
                   [fillet_px](Backend& b, const StageWork& w, StageOutput& o) {
                     o.ln_p.resize(fillet_px), o.p.resize(fillet_px), o.residual.resize(fillet_px),
                         o.score.resize(fillet_px);
                     b.pseudo_xray(w.fillets(), o.ln_p.data(), o.p.data(), o.residual.data(),
                                   o.score.data());
                   },
                   [fillet_px](const StageOutput& g, const StageOutput& r) {
                     std::string d = first_difference("ln P", g.ln_p, r.ln_p, fillet_px, 1e-6, 0);
                     if (d.empty()) d = first_difference("P", g.p, r.p, fillet_px, 0, 1e-5);
                     if (d.empty())
                       d = first_difference("residual", g.residual, r.residual, fillet_px, 2e-6, 0);
                     if (d.empty())
                       d = first_difference("z", g.score, r.score, fillet_px, 1e-5, 1e-5);
                     return d;
                   }});
  // The IRLS residuals in double; the sums to the rounding of another order of addition.
  const size_t nsums = w.fillet_models.size() * IRLS_SUMS;
  cases.push_back(
      {"irls", "residuals 1e-12, sums 1e-12 + 1e-11 relative", double(fillet_px), "pixels",
       [fillet_px, nsums](Backend& b, const StageWork& w, StageOutput& o) {
         o.r.resize(fillet_px), o.sums.resize(nsums);
         b.irls_sums(w.fillets(), o.r.data(), o.sums.data());
       },
       [fillet_px, nsums](const StageOutput& g, const StageOutput& r) {
         std::string d = first_difference("IRLS residual", g.r, r.r, fillet_px, 1e-12, 0);
         if (d.empty()) d = first_difference("IRLS sum", g.sums, r.sums, nsums, 1e-12, 1e-11);
         return d;
       }});
}

void add_dual_energy_cases(const StageWork& w, std::vector<StageCase>& cases) {
  // Dual energy: the same doubles in another order of nothing; log to a few ulp and float
  // results (a basis length one float step apart moves the lengths by the 3 x 3 inverse's
  // row times it, far inside a thousandth of their sigma).
  const int de_px = w.de_rays.pixels();
  const size_t de_n = size_t(de_px);
  cases.push_back(
      {"dual-energy",
       "NaNs exact; A, B 2e-5 mm + 2e-6 relative, covariance 1e-5 relative; "
       "lengths within 1e-3 of their sigma, sigmas 1e-5 relative",
       double(de_px), "pixels",
       [de_n](Backend& b, const StageWork& w, StageOutput& o) {
         o.basis.resize(5 * de_n), o.lengths.resize(3 * de_n), o.length_sigma.resize(3 * de_n);
         b.dual_energy(w.de_rays.batch(), w.de_params, o.basis.data(), o.lengths.data(),
                       o.length_sigma.data());
       },
       [de_n](const StageOutput& g, const StageOutput& r) {
         if (g.basis.size() < 5 * de_n || g.lengths.size() < 3 * de_n ||
             g.length_sigma.size() < 3 * de_n)
           return std::string("dual energy: too few items");
         for (size_t p = 0; p < de_n; ++p) {
           const float* gb = &g.basis[5 * p];
           const float* rb = &r.basis[5 * p];
           std::ostringstream s;
           s.precision(9);
           for (int i = 0; i < 5; ++i) {
             const bool ok =
                 i < 2 ? within(gb[i], rb[i], 2e-5, 2e-6) : within(gb[i], rb[i], 1e-12, 1e-5);
             if (!ok) {
               s << "basis " << i << " of pixel " << p << ": " << gb[i] << ", the reference "
                 << rb[i];
               return s.str();
             }
           }
           for (size_t m = 0; m < 3; ++m) {
             const size_t i = 3 * p + m;
             const double sd = r.length_sigma[i];
             if (!within(g.lengths[i], r.lengths[i], 1e-3 * (std::isnan(sd) ? 0 : sd), 0) ||
                 !within(g.length_sigma[i], sd, 0, 1e-5)) {
               s << "length " << m << " of pixel " << p << ": " << g.lengths[i] << " +- "
                 << g.length_sigma[i] << ", the reference " << r.lengths[i] << " +- " << sd;
               return s.str();
             }
           }
         }
         return std::string();
       }});
  cases.push_back(
      {"dual-energy-bone", "bone 1e-5 mm + 1e-5 relative, its sigma 1e-5 relative", double(de_px),
       "pixels",
       [de_n](Backend& b, const StageWork& w, StageOutput& o) {
         o.bone.resize(de_n), o.bone_sigma.resize(de_n);
         b.dual_energy_bone(w.de_bone(), w.de_params, o.bone.data(), o.bone_sigma.data());
       },
       [de_n](const StageOutput& g, const StageOutput& r) {
         std::string d = first_difference("bone", g.bone, r.bone, de_n, 1e-5, 1e-5);
         if (d.empty())
           d = first_difference("bone sigma", g.bone_sigma, r.bone_sigma, de_n, 0, 1e-5);
         return d;
       }});
}

}  // namespace

std::vector<StageCase> stage_cases(const StageWork& w) {
  std::vector<StageCase> cases;
  add_line_cases(w, cases);
  add_fillet_cases(w, cases);
  add_dual_energy_cases(w, cases);
  return cases;
}

}  // namespace rangex
