// One lane after the line stages: its thickness lines and X-ray lines into the lane's
// assembly, and every fillet it cuts through the inspection (and, on request, the
// X-ray-only baseline). The line stages run on a backend, for one lane (offline tools) or
// for a batch of every lane (the server); whoever ran them pushes each lane's lines here.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/inspection.h"
#include "pipeline/lane_assembly.h"
#include "pipeline/line_pipeline.h"

namespace rangex {

struct LaneProcessorOptions {
  bool baseline = true;      // also run the X-ray-only baseline on every fillet
  bool keep_images = false;  // keep pseudo-X-ray / residual / z images in the results
};

struct InspectedFillet {
  FilletImage image;  // pixel data dropped unless images are kept
  FilletResult result;
  FilletResult baseline;  // decision of the X-ray-only baseline (when enabled)
  double inspect_ms = 0;  // compensation + detection time of this fillet
};

// A fillet's inspection as the lane processor runs it (and the baseline, on request); the
// image keeps its pixels only when images are kept.
InspectedFillet inspect_image(FilletImage&& img, const InspectionParams& p,
                              const LaneProcessorOptions& opt);

class LaneProcessor {
 public:
  using FilletSink = std::function<void(InspectedFillet&&)>;
  using ImageSink = std::function<void(FilletImage&&)>;

  // Each fillet the assembly cuts is inspected here and handed to `sink`; or, with `images`,
  // handed uninspected to `images` (a server inspects on another thread, so that a fillet's
  // decision does not wait behind other lanes' lines).
  LaneProcessor(const LaneConfig& lane, LaneProcessorOptions opt, FilletSink sink,
                ImageSink images = {});

  // One line: its thickness line (detector pixels, with valid flags) from the line stages,
  // its X-ray line and its encoder count. blind: neither camera saw the stripe anywhere on
  // the line (lost or black frames): its thickness is unknown, not a bare belt.
  void push(const float* thickness, const uint8_t* valid, const uint16_t* xray, int64_t encoder,
            bool blind = false, const uint16_t* xray_high = nullptr);
  // Lines first .. first + count - 1 of `results`, all of this lane, with their X-ray lines
  // ([line][pixel]) and encoder counts.
  void push(const LineResults& results, int first, int count, const uint16_t* xray,
            const int64_t* encoders);
  void push_missing(int64_t encoder);
  // Whether a line's fused profile (grid samples) holds no valid sample at all.
  static bool blind(const uint8_t* profile_valid, size_t grid_samples);
  // Ends the open fillets as not inspected (an encoder reset, a lane no longer fed, a
  // processing error); the next line may have any count.
  void restart(const std::string& reason);
  void finish();  // closes the open fillets

  const AssemblyStats& assembly() const { return assembler_.stats(); }
  void set_next_fillet_id(int64_t id) { assembler_.set_next_id(id); }
  int64_t next_fillet_id() const { return assembler_.next_id(); }
  const std::string& last_restart() const { return assembler_.last_restart(); }
  bool quiet() const { return assembler_.quiet(); }
  int64_t pending_from() const { return assembler_.pending_from(); }
  // New thresholds or calibration for the assembly and the inspection (the caller updates
  // the backend's tables); applied only when quiet().
  void reconfigure(const LaneConfig& lane);
  const LaneConfig& lane() const { return lane_; }
  double inspection_seconds() const { return inspect_s_; }

 private:
  LaneConfig lane_;
  LaneProcessorOptions opt_;
  FilletSink sink_;
  ImageSink images_;
  LaneAssembler assembler_;
  std::vector<float> line_;
  double inspect_s_ = 0;
};

}  // namespace rangex
