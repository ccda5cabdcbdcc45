// The CPU reference of the per-line stages over one batch: stripe extraction, rectification,
// two-camera fusion and fan-beam projection. Lines of any lanes may share a batch as long as
// the lanes agree on frame size, fusion grid size and detector pixels.
#pragma once
#include <cstdint>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/profile_fusion.h"
#include "pipeline/ray_table.h"
#include "pipeline/rectify_table.h"
#include "pipeline/stripe_extract.h"

namespace rangex {

struct LineBatch {
  int lines = 0;
  std::vector<uint8_t> frames;  // [line][camera][row][column]
  std::vector<int> lane_slot;   // per line: index of its lane in the pipeline's lane list
};

struct LineResults {
  StripeOutput stripes;     // [line][camera][column]
  std::vector<float> x, z;  // rectified, [line][camera][column]
  std::vector<uint8_t> xz_valid;
  std::vector<float> profile;  // fused height, [line][grid]
  std::vector<uint8_t> profile_valid;
  std::vector<float> thickness;  // X-ray path thickness, [line][detector pixel]
  std::vector<uint8_t> thickness_valid;
  FusionStats fusion;
};

class LinePipeline {
 public:
  // threads: workers for the stripe stage, the one that reads every pixel.
  // vector_blocks false: the portable stripe groups whatever the CPU has.
  explicit LinePipeline(std::vector<LaneConfig> lanes, int threads = 1, bool vector_blocks = true);

  int slot_of(int lane_id) const;  // throws Error for an unknown lane
  const LaneConfig& lane(int slot) const { return lanes_[slot]; }
  int width() const { return width_; }
  int height() const { return height_; }
  int grid_samples() const { return grid_n_; }
  int pixels() const { return pixels_; }
  const RectifyTable& table(int slot, int camera) const { return tables_[slot * 2 + camera]; }
  // A lane's new configuration (calibration, thresholds); sizes must stay as they are.
  void update_lane(int slot, const LaneConfig& lane);

  void run(const LineBatch& batch, LineResults& out) const;
  // The same over frames in caller memory: lines x 2 frames, lane_slot per line.
  void run(const uint8_t* frames, int lines, const int* lane_slot, LineResults& out) const;

  // The stages one by one (frame_slot = lane slot * 2 + camera; lane_slot per line).
  void stripes(const uint8_t* frames, int count, const int* frame_slot, StripeOutput& out) const;
  void rectify_rows(const float* row, const uint8_t* valid, int count, const int* frame_slot,
                    float* x, float* z, uint8_t* out_valid) const;
  void fuse(const float* x, const float* z, const uint8_t* valid, int lines, const int* lane_slot,
            float* profile, uint8_t* profile_valid, FusionStats* stats) const;
  void project(const float* profile, const uint8_t* profile_valid, int lines, const int* lane_slot,
               float* thickness, uint8_t* thickness_valid) const;

 private:
  void check_shape(const LaneConfig& l) const;
  std::vector<LaneConfig> lanes_;
  std::vector<StripeSlot> stripe_slots_;  // [lane][camera]
  std::vector<RectifyTable> tables_;      // [lane][camera]
  std::vector<FusionParams> fusion_;
  std::vector<FanBeam> beams_;
  std::vector<RayTable> rays_;  // [lane]: each detector pixel's cells, built per calibration
  int width_ = 0, height_ = 0, grid_n_ = 0, pixels_ = 0;
  int threads_ = 1;
  bool vector_blocks_ = true;
};

}  // namespace rangex
