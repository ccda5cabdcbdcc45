// A batch of lines on a GPU, laid out once for both device hosts (OpenCL and Vulkan): the
// same 19 arrays, the same sizes, and the same read-back of the 14 outputs into LineResults.
// A host supplies only its buffer type and how one buffer is made, read or copied.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "backends/lane_tables.h"
#include "pipeline/line_pipeline.h"
#include "shared/lane_tables.h"

namespace rangex {

// The extents of a batch: cols = lines x 2 cameras x W columns, H frame rows, G fusion grid
// points and P X-ray pixels a line.
struct LineExtents {
  size_t lines, cols, H, G, P;
  static LineExtents of(const KernelTables& t, int lines);
};

// Where a batch's outputs land on the host: floats straight into LineResults, flags (int on
// the device) and fusion counts into staging, unpacked by finish().
class LineReadback {
 public:
  static constexpr size_t kOutputs = 14;
  // Sizes out for the batch; the host address of each output, in DeviceLines::outputs' order.
  std::array<void*, kOutputs> prepare(const LineExtents& e, LineResults& out);
  // After the reads: flags into out, fusion counts summed into out.fusion.
  void finish(LineResults& out);

 private:
  LineExtents e_{};
  std::vector<int32_t> valid_, xz_valid_, profile_valid_, thickness_valid_;
  std::vector<kernel::FusionCountK> counts_;
};

// The fusion kernel's per-line counts of `lines` lines added to `stats`.
void add_fusion_counts(const kernel::FusionCountK* counts, size_t lines, FusionStats& stats);

template <class B>
struct DeviceLines {
  int lines = 0;                               // the batch size the arrays were made for
  B frames, frame_slot, lane_slot;             // inputs
  B row, peak, width, asym, centroid, valid;   // stripes, a column each
  B x, z, xz_valid;                            // rectified, a column each
  B cam, profile, profile_valid, counts, top;  // fusion
  B thickness, thickness_valid;                // projection, an X-ray pixel each

  // Every array with its bytes for the batch and whether the host writes it.
  template <class F>
  void each(const LineExtents& e, F&& f) {
    f(frames, e.cols * e.H, true);
    f(frame_slot, e.lines * 2 * 4, true);
    f(lane_slot, e.lines * 4, true);
    for (B* b : {&row, &peak, &width, &asym, &centroid, &valid, &x, &z, &xz_valid})
      f(*b, e.cols * 4, false);
    f(cam, e.lines * 2 * e.G * 4, false);
    f(profile, e.lines * e.G * 4, false);
    f(profile_valid, e.lines * e.G * 4, false);
    f(counts, e.lines * sizeof(kernel::FusionCountK), false);
    f(top, e.lines * 4, false);
    f(thickness, e.lines * e.P * 4, false);
    f(thickness_valid, e.lines * e.P * 4, false);
  }
  std::vector<B*> all() {
    std::vector<B*> v;
    each(LineExtents{}, [&](B& b, size_t, bool) { v.push_back(&b); });
    return v;
  }
  // The outputs read back after a batch, output k with its bytes: every array the kernels
  // write but the fusion's intermediates (cam, top), in each()'s order.
  template <class F>
  void outputs(const LineExtents& e, F&& f) {
    size_t k = 0;
    each(e, [&](B& b, size_t bytes, bool input) {
      if (!input && &b != &cam && &b != &top) f(b, bytes, k++);
    });
  }
};

}  // namespace rangex
