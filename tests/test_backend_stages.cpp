// One suite, every backend (ggml's test-backend-ops, ncnn's testutil): each stage's cases are
// written once and run on every backend against the CPU reference, with the tolerance the
// case declares: valid flags, peaks and widths exactly; sub-pixel rows, mm and fusion counts
// within a stated bound. Device buffers carry guard bytes, checked after every call.
//
// A backend that cannot start on this machine is skipped and says why, unless
// RANGEX_REQUIRE_BACKENDS names it: then it fails (the test command requires opencl on
// PoCL and vulkan on lavapipe).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <sstream>

#include "backend_cases.h"
#include "backends/backend_error.h"
#include "backends/registry.h"
#include "backends/robust_fit_batch.h"
#include "backends/verify.h"
#include "core/error.h"
#include "core/lane_config.h"
#include "offline/dual_energy_work.h"
#include "offline/stage_cases.h"
#include "pipeline/pseudo_xray.h"
#include "pipeline/stripe_extract.h"
#include "sim/plant_simulator.h"
#include "stripe_frames.h"

using namespace rangex;
using namespace rangex::test;

namespace {

std::vector<StripeSlot> stripe_slots(const std::vector<LaneConfig>& lanes) {
  std::vector<StripeSlot> s;
  for (const auto& l : lanes)
    for (int c = 0; c < 2; ++c) s.push_back({l.stripe, l.cameras[c].scatter});
  return s;
}

void expect_near_or_both_nan(float a, float b, double tol, const std::string& what) {
  if (std::isnan(a) || std::isnan(b)) {
    EXPECT_TRUE(std::isnan(a) && std::isnan(b)) << what << ": " << a << " vs " << b;
    return;
  }
  EXPECT_NEAR(a, b, tol) << what;
}

class OnEveryBackend : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    const std::string name = GetParam();
    try {
      BackendRequest req;
      req.name = name;
      req.guards = true;
      backend_ = create_backend(req);
    } catch (const std::exception& e) {
      if (required(name)) FAIL() << name << " is required here but cannot start: " << e.what();
      GTEST_SKIP() << name << " cannot start on this machine: " << e.what();
    }
  }
  void use(const std::vector<LaneConfig>& lanes) {
    backend_->set_lanes(lanes);
    reference_ = std::make_unique<LinePipeline>(lanes, 1);
  }
  std::unique_ptr<Backend> backend_;
  std::unique_ptr<LinePipeline> reference_;  // the CPU reference of every stage
};

// Stripes against extract_stripes_reference: flags, peaks, widths exact; rows, centroids and
// asymmetries within 1e-4 px.
void expect_stripes_equal(const StripeOutput& got, const StripeOutput& ref, size_t n) {
  int bad = 0;
  for (size_t i = 0; i < n && bad < 10; ++i) {
    const std::string at = "column " + std::to_string(i);
    const bool ok =
        got.valid[i] == ref.valid[i] && got.peak[i] == ref.peak[i] && got.width[i] == ref.width[i];
    EXPECT_EQ(got.valid[i], ref.valid[i]) << at;
    EXPECT_EQ(got.peak[i], ref.peak[i]) << at;
    EXPECT_EQ(got.width[i], ref.width[i]) << at;
    bad += !ok;
    if (!ref.valid[i]) {
      EXPECT_TRUE(std::isnan(got.row[i])) << at;
      continue;
    }
    expect_near_or_both_nan(got.row[i], ref.row[i], Tolerance::kRowPx, at + " row");
    expect_near_or_both_nan(got.centroid[i], ref.centroid[i], Tolerance::kRowPx, at + " centroid");
    expect_near_or_both_nan(got.asym[i], ref.asym[i], Tolerance::kRowPx, at + " asym");
  }
}

}  // namespace

TEST_P(OnEveryBackend, StripesOfEveryMethodWithGlareSaturationAndFlatTops) {
  auto lanes = three_lanes();
  const test::Frames fr = test::make_frames(12, 640, 200, 7);
  std::vector<int> slot;
  for (int f = 0; f < fr.count; ++f) slot.push_back(f % 6);  // every (lane, camera)
  for (StripeMethod m : {StripeMethod::kCentroid, StripeMethod::kSquared, StripeMethod::kBinary,
                         StripeMethod::kGaussian3, StripeMethod::kParabola, StripeMethod::kShifted,
                         StripeMethod::kModified}) {
    SCOPED_TRACE(std::string(stripe_method_name(m)));
    lanes[0].stripe.method = lanes[1].stripe.method = m;  // lane 2 keeps binary
    use(lanes);
    StripeOutput got, ref;
    backend_->stripes(fr.px.data(), fr.count, slot.data(), got);
    const auto slots = stripe_slots(lanes);
    extract_stripes_reference(fr.px.data(), fr.count, 640, 200, slot.data(), slots.data(), ref);
    expect_stripes_equal(got, ref, size_t(fr.count) * 640);
  }
}

TEST_P(OnEveryBackend, StripesOfRaggedWidthAndOfOneLine) {
  const auto lanes = three_lanes(600, 200);
  use(lanes);
  const test::Frames fr = test::make_frames(2, 600, 200, 8);  // one line: two frames
  const std::vector<int> slot = {4, 5};
  StripeOutput got, ref;
  backend_->stripes(fr.px.data(), fr.count, slot.data(), got);
  const auto slots = stripe_slots(lanes);
  extract_stripes_reference(fr.px.data(), fr.count, 600, 200, slot.data(), slots.data(), ref);
  expect_stripes_equal(got, ref, size_t(fr.count) * 600);
}

TEST_P(OnEveryBackend, StripesOfEmptyAndSaturatedFrames) {
  const auto lanes = three_lanes();
  use(lanes);
  std::vector<uint8_t> px(size_t(4) * 640 * 200, 0);
  std::fill(px.begin() + 640 * 200, px.begin() + 2 * 640 * 200, 255);  // all saturated
  for (int c = 0; c < 640; ++c) px[size_t(2) * 640 * 200 + size_t(100) * 640 + c] = 255;  // one row
  const std::vector<int> slot = {0, 1, 2, 3};
  StripeOutput got, ref;
  backend_->stripes(px.data(), 4, slot.data(), got);
  const auto slots = stripe_slots(lanes);
  extract_stripes_reference(px.data(), 4, 640, 200, slot.data(), slots.data(), ref);
  expect_stripes_equal(got, ref, size_t(4) * 640);
}

TEST_P(OnEveryBackend, RectificationOfLanesWithDifferentCalibrations) {
  const auto lanes = three_lanes();
  use(lanes);
  const int count = 18, width = 640;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> row(0.f, 199.f);
  std::vector<float> rows(size_t(count) * width);
  std::vector<uint8_t> valid(rows.size());
  std::vector<int> slot;
  for (int f = 0; f < count; ++f) slot.push_back(f % 6);
  for (size_t i = 0; i < rows.size(); ++i) {
    valid[i] = rng() % 7 != 0;
    rows[i] = valid[i] ? row(rng) : NAN;
  }
  rows[5] = 0.f;  // the table's edges
  rows[6] = 199.f;
  valid[5] = valid[6] = 1;
  std::vector<float> x(rows.size()), z(rows.size()), rx(rows.size()), rz(rows.size());
  std::vector<uint8_t> v(rows.size()), rv(rows.size());
  backend_->rectify(rows.data(), valid.data(), count, slot.data(), x.data(), z.data(), v.data());
  reference_->rectify_rows(rows.data(), valid.data(), count, slot.data(), rx.data(), rz.data(),
                           rv.data());
  for (size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(v[i], rv[i]) << i;
    expect_near_or_both_nan(x[i], rx[i], Tolerance::kRectifiedMm, "x " + std::to_string(i));
    expect_near_or_both_nan(z[i], rz[i], Tolerance::kRectifiedMm, "z " + std::to_string(i));
  }
}

TEST_P(OnEveryBackend, FusionAndProjectionOfSimulatedFilletsOnThreeLanes) {
  const auto lanes = three_lanes();
  use(lanes);
  const SimLines sl(lanes, 8, 170);  // 24 lines through a fillet
  LineResults r;
  reference_->run(sl.frames.data(), sl.lines, sl.lane_slot.data(), r);
  // Some columns lost, so that gaps are filled and left open.
  std::vector<uint8_t> valid = r.xz_valid;
  for (size_t i = 0; i < valid.size(); i += 97) valid[i] = 0;
  for (size_t i = 3000; i < 3040; ++i) valid[i] = 0;
  const int G = reference_->grid_samples(), P = reference_->pixels();
  std::vector<float> prof(size_t(sl.lines) * G), rprof(prof.size());
  std::vector<uint8_t> pv(prof.size()), rpv(prof.size());
  FusionStats st, rst;
  backend_->fuse(r.x.data(), r.z.data(), valid.data(), sl.lines, sl.lane_slot.data(), prof.data(),
                 pv.data(), &st);
  reference_->fuse(r.x.data(), r.z.data(), valid.data(), sl.lines, sl.lane_slot.data(),
                   rprof.data(), rpv.data(), &rst);
  for (size_t i = 0; i < prof.size(); ++i) {
    ASSERT_EQ(pv[i], rpv[i]) << "sample " << i;
    expect_near_or_both_nan(prof[i], rprof[i], Tolerance::kProfileMm,
                            "profile " + std::to_string(i));
  }
  EXPECT_EQ(st.both, rst.both);
  EXPECT_EQ(st.single, rst.single);
  EXPECT_EQ(st.conflict, rst.conflict);
  EXPECT_EQ(st.filled, rst.filled);
  EXPECT_EQ(st.missing, rst.missing);
  EXPECT_GT(rst.filled, 0);
  // Projection of the reference profiles, with invalid samples inside the meat.
  for (size_t i = 500; i < rpv.size(); i += 1001 * 3) rpv[i] = 0;
  std::vector<float> t(size_t(sl.lines) * P), rt(t.size());
  std::vector<uint8_t> tv(t.size()), rtv(t.size());
  backend_->project(rprof.data(), rpv.data(), sl.lines, sl.lane_slot.data(), t.data(), tv.data());
  reference_->project(rprof.data(), rpv.data(), sl.lines, sl.lane_slot.data(), rt.data(),
                      rtv.data());
  size_t meat = 0, invalid = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    ASSERT_EQ(tv[i], rtv[i]) << "pixel " << i;
    expect_near_or_both_nan(t[i], rt[i], Tolerance::kThicknessMm, "thickness " + std::to_string(i));
    meat += rtv[i] && rt[i] > 1.f;
    invalid += !rtv[i];
  }
  EXPECT_GT(meat, 100u);
  EXPECT_GT(invalid, 0u);
}

TEST_P(OnEveryBackend, FusionOfCraftedPolylinesGapsAtTheLimitConflictsAndFolds) {
  const auto lanes = three_lanes();
  use(lanes);
  // Columns 0.15 mm apart over the grid, both cameras the same surface (camera 1 a little
  // off: within or beyond the lane's agreement tolerance), then per line runs of columns lost
  // on both cameras, 1 to 40 long, so that gaps of every length around max_gap (5 and 15
  // samples) occur; a fold (x turning back) and a jump beyond max_column_step.
  const int lines = 60, W = 640;
  std::mt19937 rng(5);
  std::vector<float> x(size_t(lines) * 2 * W), z(x.size());
  std::vector<uint8_t> valid(x.size(), 1);
  std::vector<int> lane_slot;
  for (int l = 0; l < lines; ++l) {
    lane_slot.push_back(l % 3);
    const float off = (l % 4 == 0) ? 0.8f : 0.1f;  // lane 1 agrees within 0.5 mm only at 0.1
    for (int cam = 0; cam < 2; ++cam)
      for (int c = 0; c < W; ++c) {
        const size_t o = (size_t(l) * 2 + cam) * W + c;
        x[o] = -48.f + 0.15f * c;
        z[o] = 10.f + 8.f * std::sin(0.02f * c) + (cam ? off : 0.f);
      }
    const size_t f0 = size_t(l) * 2 * W, f1 = f0 + W;
    for (int c = 300; c < 310; ++c) x[f0 + c] = x[f0 + 300] - 0.1f * (c - 300);  // a fold
    x[f1 + 400] += 3.f;                                                          // a jump
    for (int run = 0; run < 6; ++run) {
      const int len = 1 + int(rng() % 40), at = 20 + int(rng() % 560);
      for (int c = at; c < std::min(W, at + len); ++c) valid[f0 + c] = valid[f1 + c] = 0;
    }
  }
  const int G = reference_->grid_samples();
  std::vector<float> prof(size_t(lines) * G), rprof(prof.size());
  std::vector<uint8_t> pv(prof.size()), rpv(prof.size());
  FusionStats st, rst;
  backend_->fuse(x.data(), z.data(), valid.data(), lines, lane_slot.data(), prof.data(), pv.data(),
                 &st);
  reference_->fuse(x.data(), z.data(), valid.data(), lines, lane_slot.data(), rprof.data(),
                   rpv.data(), &rst);
  for (size_t i = 0; i < prof.size(); ++i) {
    ASSERT_EQ(pv[i], rpv[i]) << "line " << i / G << " sample " << i % G;
    expect_near_or_both_nan(prof[i], rprof[i], Tolerance::kProfileMm,
                            "profile " + std::to_string(i));
  }
  EXPECT_EQ(st.both, rst.both);
  EXPECT_EQ(st.single, rst.single);
  EXPECT_EQ(st.conflict, rst.conflict);
  EXPECT_EQ(st.filled, rst.filled);
  EXPECT_EQ(st.missing, rst.missing);
  EXPECT_GT(rst.conflict, 0);
  EXPECT_GT(rst.filled, 0);
}

TEST_P(OnEveryBackend, ProjectionOfCraftedProfilesStepsEdgesAndInvalidSamples) {
  const auto lanes = three_lanes();
  use(lanes);
  // Profiles with plateaus, steep steps, heights below the belt, and invalid samples at the
  // grid's first and last cells and inside the meat; rays from three source positions.
  const int lines = 30, G = reference_->grid_samples(), P = reference_->pixels();
  std::mt19937 rng(9);
  std::vector<float> prof(size_t(lines) * G);
  std::vector<uint8_t> pv(prof.size(), 1);
  std::vector<int> lane_slot;
  for (int l = 0; l < lines; ++l) {
    lane_slot.push_back(l % 3);
    float* h = &prof[size_t(l) * G];
    uint8_t* v = &pv[size_t(l) * G];
    const float lo = (l % 2) ? -95.f : -60.f, hi = (l % 2) ? 95.f : 50.f;  // meat under all rays
    for (int g = 0; g < G; ++g) {
      const float xg = -100.f + 0.2f * g;
      h[g] = (xg > lo && xg < hi) ? 12.f + 10.f * std::cos(0.05f * xg) : -0.3f;
      if (xg > 10 && xg < 12) h[g] = 40.f;  // a steep wall
    }
    v[0] = l % 5 != 0;
    v[G - 1] = l % 5 != 1;
    for (int k = 0; k < 1 + l % 3; ++k) v[25 + int(rng() % 950)] = 0;  // where the rays go
  }
  std::vector<float> t(size_t(lines) * P), rt(t.size());
  std::vector<uint8_t> tv(t.size()), rtv(t.size());
  backend_->project(prof.data(), pv.data(), lines, lane_slot.data(), t.data(), tv.data());
  reference_->project(prof.data(), pv.data(), lines, lane_slot.data(), rt.data(), rtv.data());
  size_t invalid = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    ASSERT_EQ(tv[i], rtv[i]) << "line " << i / P << " pixel " << i % P;
    expect_near_or_both_nan(t[i], rt[i], Tolerance::kThicknessMm, "thickness " + std::to_string(i));
    invalid += !rtv[i];
  }
  EXPECT_GT(invalid, 0u);
}

TEST_P(OnEveryBackend, LinePathOfMixedLaneBatchesTwoInFlight) {
  const auto lanes = three_lanes();
  use(lanes);
  const SimLines a(lanes, 5, 160), b(lanes, 1, 200);  // 15 lines, then one line per lane
  const size_t frame = size_t(640) * 200;
  auto fill = [&](LineBatchSlot& s, const SimLines& src) {
    std::copy(src.frames.begin(), src.frames.end(), s.frames());
    std::copy(src.lane_slot.begin(), src.lane_slot.end(), s.lane_slot());
  };
  LineBatchSlot& sa = backend_->acquire(a.lines);
  ASSERT_GE(sa.capacity(), a.lines);
  fill(sa, a);
  backend_->submit(sa);
  LineBatchSlot& sb = backend_->acquire(b.lines);
  fill(sb, b);
  backend_->submit(sb);
  EXPECT_THROW(backend_->acquire(1), Error);  // two in flight at most
  LineResults ra, rb, qa, qb;
  backend_->collect(sa, ra);
  backend_->collect(sb, rb);
  reference_->run(a.frames.data(), a.lines, a.lane_slot.data(), qa);
  reference_->run(b.frames.data(), b.lines, b.lane_slot.data(), qb);
  for (auto [got, ref, lines] : {std::tuple{&ra, &qa, a.lines}, std::tuple{&rb, &qb, b.lines}}) {
    expect_stripes_equal(got->stripes, ref->stripes, size_t(lines) * 2 * 640);
    ASSERT_EQ(got->thickness.size(), ref->thickness.size());
    for (size_t i = 0; i < got->thickness.size(); ++i) {
      ASSERT_EQ(got->thickness_valid[i], ref->thickness_valid[i]) << i;
      expect_near_or_both_nan(got->thickness[i], ref->thickness[i], Tolerance::kThicknessMm,
                              "thickness");
    }
    EXPECT_EQ(got->fusion.both, ref->fusion.both);
    EXPECT_EQ(got->fusion.missing, ref->fusion.missing);
  }
  (void)frame;
}

TEST_P(OnEveryBackend, ACalibrationUpdateReachesTheNextBatch) {
  auto lanes = three_lanes();
  use(lanes);
  const SimLines sl(lanes, 4, 175);
  auto run = [&](LineResults& r) {
    LineBatchSlot& s = backend_->acquire(sl.lines);
    std::copy(sl.frames.begin(), sl.frames.end(), s.frames());
    std::copy(sl.lane_slot.begin(), sl.lane_slot.end(), s.lane_slot());
    backend_->submit(s);
    backend_->collect(s, r);
  };
  LineResults before, after, ref;
  run(before);
  lanes[1].laser.offset_mm = 1.5;  // a new calibration of lane 1 only
  backend_->update_lane(1, lanes[1]);
  reference_->update_lane(1, lanes[1]);
  run(after);
  reference_->run(sl.frames.data(), sl.lines, sl.lane_slot.data(), ref);
  size_t changed = 0;
  for (size_t i = 0; i < after.x.size(); ++i) {
    expect_near_or_both_nan(after.x[i], ref.x[i], Tolerance::kRectifiedMm, "x");
    expect_near_or_both_nan(after.z[i], ref.z[i], Tolerance::kRectifiedMm, "z");
    changed += std::abs(after.z[i] - before.z[i]) > 0.01f;
  }
  EXPECT_GT(changed, 0u);
}

// A batch of fillets for the pseudo-X-ray stages: sizes from empty to more than a work-group
// many times over, a mask with holes, X-ray lines through bone (low DN) and near saturation,
// models at the OLS start (scale 0) and in later iterations, with and without a noise model.
struct FilletCases {
  std::vector<float> thickness;
  std::vector<uint16_t> xray;
  std::vector<uint8_t> use;
  std::vector<int32_t> offsets{0};
  std::vector<FilletModel> models;
  FilletBatch batch() const {
    return {thickness.data(), xray.data(),        use.data(),
            offsets.data(),   int(models.size()), models.data()};
  }
  FilletCases() {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    const int sizes[] = {0, 1, 255, 257, 5000, 70000, 3};
    int k = 0;
    for (int n : sizes) {
      const double b0 = std::log(3600.0) + 0.1 * k, b1 = -0.03 - 0.002 * k;
      for (int i = 0; i < n; ++i) {
        const double t = 30 * u(rng);
        thickness.push_back(float(t));
        // ln I about the model, outliers (bone) now and then; DN within 1 .. 65535.
        double ln = b0 + b1 * t + 0.02 * (u(rng) - 0.5) - (u(rng) < 0.03 ? 0.4 : 0.0);
        if (i % 97 == 5) ln = std::log(65535.0);
        if (i % 89 == 7) ln = 0;  // DN 1
        xray.push_back(uint16_t(std::clamp(std::lround(std::exp(ln)), 1L, 65535L)));
        use.push_back(uint8_t(u(rng) > 0.1));
      }
      offsets.push_back(offsets.back() + n);
      const double scale = k % 2 ? 0.01 + 0.005 * k : 0.0;
      const double a = k % 3 ? 2.0 + k : 0.0, b = k % 3 ? 400.0 * k : 0.0;
      models.push_back({b0 + 0.001, b1 * 1.01, scale, 5.0, a, b});
      ++k;
    }
  }
};

bool near_rel(double a, double b, double rel, double abs_tol) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::fabs(a - b) <= abs_tol + rel * std::fabs(b);
}

// ln P within float rounding of the double model, P within exp's error (relative), residual
// and z to float rounding of the same values; the IRLS residuals in double; the sums to the
// rounding of another summation order.
TEST_P(OnEveryBackend, PseudoXrayMapAndIrlsSumsOfABatchOfFillets) {
  const FilletCases fc;
  const FilletBatch b = fc.batch();
  const size_t n = size_t(b.pixels());
  std::vector<float> lp(n), p(n), res(n), z(n), rlp(n), rp(n), rres(n), rz(n);
  backend_->pseudo_xray(b, lp.data(), p.data(), res.data(), z.data());
  pseudo_xray_map(b, rlp.data(), rp.data(), rres.data(), rz.data());
  size_t off = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool ok = near_rel(lp[i], rlp[i], 0, 1e-6) && near_rel(p[i], rp[i], 1e-5, 0) &&
                    near_rel(res[i], rres[i], 0, 2e-6) && near_rel(z[i], rz[i], 1e-5, 1e-5);
    if (!ok && off++ < 5)
      ADD_FAILURE() << "pixel " << i << ": ln P " << lp[i] << " / " << rlp[i] << ", P " << p[i]
                    << " / " << rp[i] << ", residual " << res[i] << " / " << rres[i] << ", z "
                    << z[i] << " / " << rz[i];
  }
  EXPECT_EQ(off, 0u);
  std::vector<double> r(n), rr(n), sums(b.fillets * IRLS_SUMS), rsums(sums.size());
  backend_->irls_sums(b, r.data(), sums.data());
  irls_sums(b, rr.data(), rsums.data());
  for (size_t i = 0; i < n; ++i) ASSERT_TRUE(near_rel(r[i], rr[i], 0, 1e-12)) << "pixel " << i;
  for (size_t i = 0; i < sums.size(); ++i)
    EXPECT_TRUE(near_rel(sums[i], rsums[i], 1e-11, 1e-12))
        << "fillet " << i / IRLS_SUMS << " sum " << i % IRLS_SUMS << ": " << sums[i] << " / "
        << rsums[i];
  // The weights did their work: a later iteration's sum of weights is below the pixel count.
  EXPECT_LT(rsums[3 * IRLS_SUMS], double(fc.offsets[4] - fc.offsets[3]));
  // A batch that names falling offsets is refused.
  std::vector<int32_t> bad = fc.offsets;
  std::swap(bad[2], bad[3]);
  FilletBatch bb = b;
  bb.offsets = bad.data();
  EXPECT_THROW(backend_->irls_sums(bb, r.data(), sums.data()), Error);
}

// The robust fit of a batch of fillets with each iteration's per-pixel work on the backend
// and the iteration logic on the host gives fit_tukey_line's result for every fillet (the
// sums differ from the CPU's by the rounding of another order, nothing more).
TEST_P(OnEveryBackend, RobustFitOfABatchOfFilletsEqualsTheCpuFit) {
  const FilletCases fc;
  const FilletBatch b = fc.batch();
  const RobustFitOptions opt{5.0, 50, 1e-8, true};
  const std::vector<BatchFit> got = fit_tukey_lines(*backend_, b, opt);
  ASSERT_EQ(got.size(), size_t(b.fillets));
  int fitted = 0;
  for (int f = 0; f < b.fillets; ++f) {
    SCOPED_TRACE("fillet " + std::to_string(f));
    std::vector<double> t, y;
    for (int i = b.offsets[f]; i < b.offsets[f + 1]; ++i)
      if (b.use[i]) {
        t.push_back(b.thickness[i]);
        y.push_back(std::log(double(b.xray[i])));
      }
    RobustFit want;
    std::string error;
    try {
      want = fit_tukey_line(t.data(), y.data(), t.size(), opt);
    } catch (const Error& e) {
      error = e.what();
    }
    EXPECT_EQ(got[f].error.empty(), error.empty()) << got[f].error << " / " << error;
    if (!error.empty()) continue;
    ++fitted;
    const RobustFit& g = got[f].fit;
    EXPECT_NEAR(g.beta0, want.beta0, 1e-9 * std::fabs(want.beta0));
    EXPECT_NEAR(g.beta1, want.beta1, 1e-8 * std::fabs(want.beta1) + 1e-12);
    EXPECT_NEAR(g.scale, want.scale, 1e-8 * want.scale + 1e-15);
    EXPECT_EQ(g.converged, want.converged);
    EXPECT_NEAR(g.iterations, want.iterations, 1);
    EXPECT_EQ(g.n, want.n);
    EXPECT_NEAR(double(g.inliers), double(want.inliers), 1);
  }
  EXPECT_GE(fitted, 4);
}

TEST_P(OnEveryBackend, BadBatchesAreRefusedWithAClearError) {
  use(three_lanes());
  LineBatchSlot& s = backend_->acquire(1);
  std::fill(s.frames(), s.frames() + 2 * 640 * 200, uint8_t(0));
  s.lane_slot()[0] = 7;  // no such lane
  try {
    backend_->submit(s);
    LineResults r;
    backend_->collect(s, r);
    FAIL() << "a line naming lane slot 7 was processed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lane slot 7"), std::string::npos) << e.what();
  }
}

// The decomposition on this backend matches the simulator's truth within the uncertainty it
// states, material by material: rays drawn on the simulator's sandwich detector, the laser's
// thickness with 0.05 mm noise, the calibration fitted from a simulated wedge scan. The pull
// (t - truth) / sigma over 2,000 rays: mean within 0.5, spread 0.7-1.3. The bone given the
// true fat share likewise.
TEST_P(OnEveryBackend, DualEnergyLengthsOfEachMaterialMatchTheirTruth) {
  static const DualEnergyCalibrated c = calibrate_dual_energy(100000);
  struct Case {
    const char* what;
    double lean, fat, bone;
  };
  const Case cases[] = {{"25 mm lean", 25, 0, 0},
                        {"15 mm fat", 0, 15, 0},
                        {"18 lean + 7 fat", 18, 7, 0},
                        {"20 lean + 2 bone", 20, 0, 2},
                        {"30 lean + 5 fat + 1 bone", 30, 5, 1}};
  const char* names[3] = {"lean", "fat", "bone"};
  uint64_t seed = 1;
  for (const Case& k : cases) {
    SCOPED_TRACE(k.what);
    sim::RayMaterials r;
    r.lean = k.lean, r.fat = k.fat, r.bone = k.bone;
    DualEnergyRays rays;
    const int n = 2000;
    rays.add(c, r, n, 0.05, seed++);
    const size_t N = size_t(n);
    std::vector<float> basis(5 * N), len(3 * N), sd(3 * N);
    backend_->dual_energy(rays.batch(), c.params, basis.data(), len.data(), sd.data());
    const double truth[3] = {k.lean, k.fat, k.bone};
    auto expect_pulls = [&](const char* what, const float* t, const float* sg, size_t stride,
                            double want) {
      double s = 0, s2 = 0;
      for (size_t i = 0; i < N; ++i) {
        const double pull = (t[stride * i] - want) / sg[stride * i];
        s += pull, s2 += pull * pull;
      }
      const double mean = s / n, spread = std::sqrt(s2 / n - mean * mean);
      std::printf("%s %-26s %-5s pull mean %+.2f spread %.2f\n", GetParam().c_str(), k.what, what,
                  mean, spread);
      EXPECT_LT(std::abs(mean), 0.5) << what;
      EXPECT_GT(spread, 0.7) << what;
      EXPECT_LT(spread, 1.3) << what;
    };
    for (size_t m = 0; m < 3; ++m) expect_pulls(names[m], &len[m], &sd[m], 3, truth[m]);
    // Bone given the true fat share (step 4).
    const float phi = k.lean + k.fat > 0 ? float(k.fat / (k.lean + k.fat)) : 0.f;
    std::vector<float> phis(N, phi), phi_var(N, 0.f), bone(N), bone_sd(N);
    DualEnergyBoneBatch bb;
    bb.basis = basis.data(), bb.thickness = rays.thickness.data();
    bb.phi = phis.data(), bb.phi_var = phi_var.data(), bb.pixels = n;
    backend_->dual_energy_bone(bb, c.params, bone.data(), bone_sd.data());
    expect_pulls("bone given phi", bone.data(), bone_sd.data(), 1, k.bone);
  }
}

// What is not a dual-energy batch is refused, naming what is wrong; an empty batch is none.
TEST_P(OnEveryBackend, DualEnergyBatchesThatAreNoneAreRefused) {
  static const DualEnergyCalibrated c = calibrate_dual_energy(2000);
  DualEnergyRays rays;
  rays.add(c, sim::RayMaterials{20, 2}, 16, 0.05, 3);
  std::vector<float> basis(80), len(48), sd(48);
  auto refused = [&](const DualEnergyBatch& b, const DualEnergyParams& k, const char* says) {
    try {
      backend_->dual_energy(b, k, basis.data(), len.data(), sd.data());
      ADD_FAILURE() << "accepted a batch that " << says;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  DualEnergyBatch b = rays.batch();
  b.high = nullptr;
  refused(b, c.params, "without both layers");
  b = rays.batch();
  b.pixels = -3;
  refused(b, c.params, "-3 pixels");
  refused(rays.batch(), DualEnergyParams{}, "no calibration");
  DualEnergyParams nan_params = c.params;
  nan_params.minv[4] = std::numeric_limits<double>::quiet_NaN();
  refused(rays.batch(), nan_params, "no calibration");
  b = rays.batch();
  b.pixels = 0;
  EXPECT_NO_THROW(backend_->dual_energy(b, c.params, basis.data(), len.data(), sd.data()));
  DualEnergyBoneBatch bb;
  bb.basis = basis.data(), bb.thickness = rays.thickness.data(), bb.pixels = 16;
  std::vector<float> bone(16), bone_sd(16);
  EXPECT_THROW(backend_->dual_energy_bone(bb, c.params, bone.data(), bone_sd.data()), Error);
}

INSTANTIATE_TEST_SUITE_P(Backends, OnEveryBackend,
                         ::testing::Values("cpu", "cpu-portable", "opencl", "vulkan"),
                         [](const auto& info) {
                           std::string n = info.param;
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

// The stage case table (offline/stage_cases.h, which `bench --backend` times): every case on
// this backend against the CPU backend, within the tolerance the case declares.
TEST_P(OnEveryBackend, EveryStageCaseOfTheTableMatchesTheCpu) {
  const StageWork w = make_stage_work(default_lane_config(0), 3, 12, 3, 4000, 4000);
  backend_->set_lanes(w.lanes);
  const std::unique_ptr<Backend> cpu = create_backend(cpu_request());
  cpu->set_lanes(w.lanes);
  const std::vector<StageCase> cases = stage_cases(w);
  ASSERT_EQ(cases.size(), 8u);
  for (const StageCase& c : cases) {
    StageOutput got, want;
    c.run(*backend_, w, got);
    c.run(*cpu, w, want);
    EXPECT_EQ(c.compare(got, want), "") << c.stage << " (" << c.what << ")";
    // The comparison is not blind: a result moved beyond the tolerance is caught.
    if (!want.thickness.empty()) {
      StageOutput moved = want;
      for (size_t i = 0; i < moved.thickness.size(); ++i)
        if (moved.thickness_valid[i]) {
          moved.thickness[i] += 0.01f;
          break;
        }
      EXPECT_NE(c.compare(moved, want), "") << c.stage;
    }
    if (!want.bone.empty() || !want.lengths.empty()) {
      StageOutput moved = want;
      auto& v = want.bone.empty() ? moved.lengths : moved.bone;
      const auto& sd = want.bone.empty() ? moved.length_sigma : moved.bone_sigma;
      for (size_t i = 0; i < v.size(); ++i)
        if (std::isfinite(v[i])) {
          v[i] += 0.01f * sd[i];
          break;
        }
      EXPECT_NE(c.compare(moved, want), "") << c.stage;
    }
  }
}
