// A backend that fails on purpose, for tests of what the server does when a device fails
// mid-stream or computes wrong results: it runs the wrapped backend and, from the given
// batch on, throws BackendError (a failed dispatch, a lost device) or perturbs the
// thickness it returns (a result the runtime verification must catch).
#pragma once
#include <memory>

#include "backends/backend.h"

namespace rangex {

struct FaultPlan {
  int fail_after = -1;     // batches collected before every collect throws (-1: never)
  int corrupt_after = -1;  // batches collected before thickness is off by 1 mm (-1: never)
};

class FaultInjectingBackend final : public Backend {
 public:
  FaultInjectingBackend(std::unique_ptr<Backend> inner, FaultPlan plan);
  const BackendInfo& info() const override { return info_; }
  void set_lanes(const std::vector<LaneConfig>& lanes) override;
  void update_lane(int slot, const LaneConfig& lane) override;
  LineBatchSlot& acquire(int lines) override { return inner_->acquire(lines); }
  void submit(LineBatchSlot& batch) override { inner_->submit(batch); }
  void collect(LineBatchSlot& batch, LineResults& out) override;
  void stripes(const uint8_t* frames, int count, const int* frame_slot,
               StripeOutput& out) override {
    inner_->stripes(frames, count, frame_slot, out);
  }
  void rectify(const float* row, const uint8_t* valid, int count, const int* frame_slot, float* x,
               float* z, uint8_t* out_valid) override {
    inner_->rectify(row, valid, count, frame_slot, x, z, out_valid);
  }
  void fuse(const float* x, const float* z, const uint8_t* valid, int lines, const int* lane_slot,
            float* profile, uint8_t* profile_valid, FusionStats* stats) override {
    inner_->fuse(x, z, valid, lines, lane_slot, profile, profile_valid, stats);
  }
  void project(const float* profile, const uint8_t* profile_valid, int lines, const int* lane_slot,
               float* thickness, uint8_t* thickness_valid) override {
    inner_->project(profile, profile_valid, lines, lane_slot, thickness, thickness_valid);
  }
  void pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                   float* z) override {
    inner_->pseudo_xray(b, ln_p, p, residual, z);
  }
  void irls_sums(const FilletBatch& b, double* r, double* sums) override {
    inner_->irls_sums(b, r, sums);
  }
  void dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                   float* lengths, float* sigma) override {
    inner_->dual_energy(b, k, basis, lengths, sigma);
  }
  void dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k, float* bone,
                        float* bone_sigma) override {
    inner_->dual_energy_bone(b, k, bone, bone_sigma);
  }

 private:
  std::unique_ptr<Backend> inner_;
  BackendInfo info_;
  FaultPlan plan_;
  int collected_ = 0;
};

}  // namespace rangex
