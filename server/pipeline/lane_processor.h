// One lane end to end on the CPU: batches of lines through the line pipeline, the thickness
// and X-ray lines into the lane's assembly, and every fillet it cuts through the inspection
// (and, on request, the X-ray-only baseline beside it). Offline replay, the simulated plant
// and the server all drive lanes through this.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/inspection.h"
#include "pipeline/lane_assembly.h"
#include "pipeline/line_pipeline.h"

namespace rangex {

struct LaneProcessorOptions {
  int threads = 1;           // stripe-stage workers
  bool baseline = true;      // also run the X-ray-only baseline on every fillet
  bool keep_images = false;  // keep pseudo-X-ray / residual / z images in the results
};

struct InspectedFillet {
  FilletImage image;  // pixel data dropped unless images are kept
  FilletResult result;
  FilletResult baseline;  // decision of the X-ray-only baseline (when enabled)
  double inspect_ms = 0;  // compensation + detection time of this fillet
};

class LaneProcessor {
 public:
  using FilletSink = std::function<void(InspectedFillet&&)>;
  // Called after each batch with the pipeline's per-line results (camera line encoders).
  using LineObserver = std::function<void(const LineResults&, const int64_t* encoders, int count)>;

  LaneProcessor(const LaneConfig& lane, LaneProcessorOptions opt, FilletSink sink,
                LineObserver observer = {});

  // count lines: frames [line][camera][row][col], X-ray lines [line][pixel], encoder counts.
  void push(int count, const uint8_t* frames, const uint16_t* xray, const int64_t* encoders);
  void push_missing(int64_t encoder);
  // Ends the open fillets as not inspected (an encoder reset, a lane no longer fed, a
  // processing error); the next line may have any count.
  void restart(const std::string& reason);
  void finish();  // closes the open fillets

  const AssemblyStats& assembly() const { return assembler_.stats(); }
  const std::string& last_restart() const { return assembler_.last_restart(); }
  bool quiet() const { return assembler_.quiet(); }
  // A new calibration or thresholds; the caller applies it only when quiet().
  void reconfigure(const LaneConfig& lane);
  const LaneConfig& lane() const { return lane_; }
  const FusionStats& fusion() const { return results_.fusion; }
  double pipeline_seconds() const { return pipeline_s_; }
  double inspection_seconds() const { return inspect_s_; }

 private:
  LaneConfig lane_;
  LaneProcessorOptions opt_;
  FilletSink sink_;
  LineObserver observer_;
  std::unique_ptr<LinePipeline> pipe_;
  LaneAssembler assembler_;
  LineBatch batch_;
  LineResults results_;
  double pipeline_s_ = 0, inspect_s_ = 0;
};

}  // namespace rangex
