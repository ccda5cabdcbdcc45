// Offline replay: a recording through the same line stages the server runs, on the backend
// asked for (cpu, opencl, vulkan), batch by batch, with the thickness lines registered to the
// X-ray lines by the calibrated delay.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "backends/registry.h"
#include "core/plant_config.h"
#include "core/recording.h"
#include "pipeline/lane_processor.h"
#include "pipeline/line_pipeline.h"

namespace rangex {

struct ReplayOptions {
  int batch_lines = 64;
  std::optional<StripeMethod> method;      // overrides plant.yaml's stripe method
  std::vector<int> lanes;                  // empty: every lane of the recording
  BackendRequest backend = cpu_request();  // where the line stages run (threads: CPU workers)
  bool keep_images = true;                 // per-fillet pseudo-X-ray / residual images
  bool baseline = true;                    // X-ray-only baseline beside every fillet
  // A recording made under another calibration is refused unless the caller replays it
  // with a new one on purpose (rangexctl process --calibration).
  bool recalibrated = false;
  // Lines of a real line may be missing (lost frames, a device that dropped off): replayed as
  // the server takes them, the gaps bridged or fillets ended alike. The per-line arrays of
  // LaneReplay (thickness, stripe rows) are then left empty.
  bool missing_lines_ok = false;
};

struct LaneReplay {
  int lane = 0;
  int64_t lines = 0;
  int width = 0, pixels = 0;
  // X-ray path thickness registered to X-ray line k (from the camera line k - delay), mm;
  // NaN where there is no valid thickness.
  std::vector<float> thickness;
  std::vector<float> stripe_rows[2];  // per camera, lines x width, NaN where invalid
  FusionStats fusion;
  AssemblyStats assembly;
  std::vector<InspectedFillet> fillets;
  double seconds = 0;             // line stages on the backend, reading excluded
  double inspection_seconds = 0;  // assembly is negligible; compensation + detection
};

using ReplayProgress = std::function<void(int64_t done, int64_t total)>;

// `backend_info`, when given, receives what the line stages ran on.
std::vector<LaneReplay> replay_recording(const RecordingReader& rec, const PlantConfig& plant,
                                         const ReplayOptions& opt,
                                         const ReplayProgress& progress = {},
                                         BackendInfo* backend_info = nullptr);

}  // namespace rangex
