// The opencl backend: the line stages as OpenCL kernels (kernels/*.cl, embedded at build).
// A batch is one upload from pinned staging, the five kernels enqueued in order and the
// results read back, all on the batch slot's own in-order queue; the two slots' queues let
// one batch upload while the other computes. Per-lane tables are uploaded when lanes are
// set or one is updated.
#pragma once
#include <array>
#include <memory>
#include <string>

#include "backends/backend.h"

namespace rangex {

struct OpenClOptions {
  std::string device;   // "" (first GPU, else first device), an index, or a name substring
  bool guards = false;  // guard bytes around every device buffer, checked after each call
};

class OpenClBackend final : public Backend {
 public:
  explicit OpenClBackend(const OpenClOptions& opt);
  ~OpenClBackend() override;
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
  double upload_bandwidth(size_t bytes) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  BackendInfo info_;
};

}  // namespace rangex
