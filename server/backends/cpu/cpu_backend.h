// The CPU backend: the CPU pipeline (AVX-512 blocks where the CPU has them, portable groups
// otherwise) behind the backend interface. Every other backend is checked against the
// per-stage references this runs (and the stripe reference it is itself checked against).
#pragma once
#include <array>
#include <memory>

#include "backends/backend.h"

namespace rangex {

class CpuBackend final : public Backend {
 public:
  // portable: the portable stripe groups whatever the CPU has (the `cpu-portable` variant,
  // which the suite runs like any backend and the server verifies like a device).
  explicit CpuBackend(int threads = 1, bool portable = false);
  ~CpuBackend() override;
  const BackendInfo& info() const override { return info_; }
  void set_lanes(const std::vector<LaneConfig>& lanes) override;
  void update_lane(int slot, const LaneConfig& lane) override;

  LineBatchSlot& acquire(int lines) override;
  void submit(LineBatchSlot& batch) override;
  void collect(LineBatchSlot& batch, LineResults& out) override;

  void stripes(const uint8_t* frames, int count, const int* frame_slot, StripeOutput& out) override;
  void rectify(const float* row, const uint8_t* valid, int count, const int* frame_slot, float* x,
               float* z, uint8_t* out_valid) override;
  void fuse(const float* x, const float* z, const uint8_t* valid, int lines, const int* lane_slot,
            float* profile, uint8_t* profile_valid, FusionStats* stats) override;
  void project(const float* profile, const uint8_t* profile_valid, int lines, const int* lane_slot,
               float* thickness, uint8_t* thickness_valid) override;
  void pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual, float* z) override;
  void irls_sums(const FilletBatch& b, double* r, double* sums) override;
  void dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                   float* lengths, float* sigma) override;
  void dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k, float* bone,
                        float* bone_sigma) override;

 private:
  class Slot;
  const LinePipeline& pipe() const;
  BackendInfo info_;
  int threads_;
  bool portable_;
  std::unique_ptr<LinePipeline> pipe_;
  std::array<std::unique_ptr<Slot>, 2> slots_;
  int next_ = 0;
};

}  // namespace rangex
