// The compute seam: one interface over flat batch buffers that every backend (cpu, opencl,
// vulkan) implements, so that the engine and the tools do not care where a stage runs.
//
// A backend serves a set of lanes (slot = index) that share frame size, fusion grid and
// detector pixels. Per-lane tables (stripe settings, rectification tables, fusion and
// fan-beam geometry) are built and uploaded when the lanes are set or one is updated (a
// calibration activation), never per batch.
//
// The line path runs as acquire -> fill -> submit -> collect: the backend owns the staging
// memory a batch's frames are written into (pinned or host-visible on a device, so each frame
// is copied once on its way in), a submitted batch is uploaded and computed in one recorded
// sequence, and up to two batches are in flight, so that one uploads while the other
// computes. Single-stage calls take and return host memory; the suite that proves every
// backend equal to the CPU reference and the benchmarks use them.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/dual_energy.h"
#include "pipeline/line_pipeline.h"
#include "pipeline/pseudo_xray.h"

namespace rangex {

struct BackendInfo {
  std::string name;       // cpu | opencl | vulkan (a variant may add a suffix: cpu-portable)
  std::string device;     // what computes
  std::string driver;     // platform / driver version
  std::string limits;     // one line: memory, work-group size, ...
  bool emulated = false;  // a CPU emulation of a GPU API (PoCL's CPU device, lavapipe)
  // Computes between submit() and collect(), so a second batch can be filled meanwhile
  // (device backends); the CPU backend computes inside collect().
  bool overlaps = false;
  // The CPU reference itself: nothing to verify it against.
  bool reference = false;
};

// Seconds of the last collected batch (or single stage), split as the benchmarks report it.
struct StageTimes {
  double upload = 0, compute = 0, download = 0;
};

// Staging for one batch: `lines` lines of two frames each ([line][camera][row][column]) and
// each line's lane slot.
class LineBatchSlot {
 public:
  virtual ~LineBatchSlot() = default;
  int capacity() const { return capacity_; }
  uint8_t* frames() { return frames_; }
  int32_t* lane_slot() { return lane_slot_; }
  int lines = 0;

 protected:
  int capacity_ = 0;
  uint8_t* frames_ = nullptr;
  int32_t* lane_slot_ = nullptr;
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual const BackendInfo& info() const = 0;

  // The lanes served; all must share frame size, fusion grid and detector pixels.
  virtual void set_lanes(const std::vector<LaneConfig>& lanes) = 0;
  // One lane's new configuration (its slot keeps its place). No batch may be in flight.
  virtual void update_lane(int slot, const LaneConfig& lane) = 0;
  int lanes() const { return int(lanes_.size()); }
  const LaneConfig& lane(int slot) const { return lanes_.at(slot); }

  // The line path. acquire() waits while two batches are in flight.
  virtual LineBatchSlot& acquire(int lines) = 0;
  virtual void submit(LineBatchSlot& batch) = 0;
  virtual void collect(LineBatchSlot& batch, LineResults& out) = 0;

  // Single stages over host memory (slots as in LinePipeline: frame_slot = lane slot * 2 +
  // camera, lane_slot per line).
  virtual void stripes(const uint8_t* frames, int count, const int* frame_slot,
                       StripeOutput& out) = 0;
  virtual void rectify(const float* row, const uint8_t* valid, int count, const int* frame_slot,
                       float* x, float* z, uint8_t* out_valid) = 0;
  virtual void fuse(const float* x, const float* z, const uint8_t* valid, int lines,
                    const int* lane_slot, float* profile, uint8_t* profile_valid,
                    FusionStats* stats) = 0;
  virtual void project(const float* profile, const uint8_t* profile_valid, int lines,
                       const int* lane_slot, float* thickness, uint8_t* thickness_valid) = 0;

  // The pseudo-X-ray stages over a batch of fillets (pipeline/pseudo_xray.h); they need no
  // lanes set. pseudo_xray: ln P, P, residual and z per pixel. irls_sums: each pixel's
  // residual and each fillet's IRLS_SUMS weighted sums for the model in `b`.
  virtual void pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                           float* z) = 0;
  virtual void irls_sums(const FilletBatch& b, double* r, double* sums) = 0;

  // The dual-energy stages over a batch of pixels (pipeline/dual_energy.h); they need no
  // lanes set. dual_energy: each pixel's basis (A, B and their covariance: 5 floats; NaN where
  // it cannot be inverted), its lean, fat and bone lengths and their sigmas (3 each).
  // dual_energy_bone: the bone length given the fat share, and its sigma.
  virtual void dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                           float* lengths, float* sigma) = 0;
  virtual void dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k,
                                float* bone, float* bone_sigma) = 0;

  const StageTimes& last_times() const { return times_; }

  // Host-to-device copy bandwidth (bytes/s) measured over `bytes` from pinned or
  // host-visible staging into device memory, best of a few; 0 where the device reads host
  // memory in place (the CPU, unified memory) and nothing is copied.
  virtual double upload_bandwidth(size_t /*bytes*/) { return 0; }

 protected:
  std::vector<LaneConfig> lanes_;
  StageTimes times_;
};

// One batch through a backend, waited for: `lines` lines of frames ([line][camera] in
// caller memory) copied into the backend's staging, with their lane slots.
void run_batch(Backend& b, const uint8_t* frames, int lines, const int* lane_slot,
               LineResults& out);

}  // namespace rangex
