// The vulkan backend: the line stages as compute shaders (shaders/*.comp, compiled to SPIR-V
// at build). A batch is one command buffer: the upload, the five dispatches with barriers
// between them, the download; each of the two batch slots has its own, so that one batch
// records and uploads while the other computes. On devices whose memory the host can map
// (integrated GPUs, lavapipe) frames are written straight into the buffer the shader reads
// and results read where the shaders wrote them: no copies at all.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "backends/backend.h"

namespace rangex {

struct VulkanOptions {
  std::string device;   // "" (first GPU, else first device), an index, or a name substring
  bool guards = false;  // guard bytes around every buffer, checked after each call
};

struct VulkanDevice {
  std::string name;
  bool cpu = false;
};
// The devices the backend could run on (compute queue, 64-bit floats); throws BackendError
// naming what failed when no loader or driver answers.
std::vector<VulkanDevice> vulkan_devices();

class VulkanBackend final : public Backend {
 public:
  explicit VulkanBackend(const VulkanOptions& opt);
  ~VulkanBackend() override;
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
