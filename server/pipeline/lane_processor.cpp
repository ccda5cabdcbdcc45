#include "pipeline/lane_processor.h"

#include <chrono>
#include <limits>

namespace rangex {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

LaneProcessor::LaneProcessor(const LaneConfig& lane, LaneProcessorOptions opt, FilletSink sink,
                             LineObserver observer)
    : lane_(lane),
      opt_(opt),
      sink_(std::move(sink)),
      observer_(std::move(observer)),
      pipe_(std::make_unique<LinePipeline>(std::vector<LaneConfig>{lane}, opt.threads)),
      assembler_(lane, [this](FilletImage&& img) {
        const auto t0 = std::chrono::steady_clock::now();
        InspectedFillet f;
        f.result = inspect_fillet(img, lane_.inspection, opt_.keep_images);
        if (opt_.baseline) f.baseline = inspect_fillet_xray_only(img, lane_.inspection, false);
        if (!opt_.keep_images) {
          img.xray.clear();
          img.thickness.clear();
          img.mask.clear();
        }
        f.image = std::move(img);
        f.inspect_ms = 1e3 * since(t0);
        inspect_s_ += since(t0);
        sink_(std::move(f));
      }) {}

void LaneProcessor::push(int count, const uint8_t* frames, const uint16_t* xray,
                         const int64_t* encoders) {
  const size_t frame = size_t(pipe_->width()) * pipe_->height();
  batch_.lines = count;
  batch_.lane_slot.assign(count, 0);
  batch_.frames.assign(frames, frames + frame * 2 * count);
  const auto t0 = std::chrono::steady_clock::now();
  pipe_->run(batch_, results_);
  pipeline_s_ += since(t0);
  const int D = pipe_->pixels();
  std::vector<float> line(D);
  for (int k = 0; k < count; ++k) {
    for (int i = 0; i < D; ++i) {
      const size_t o = size_t(k) * D + i;
      line[i] = results_.thickness_valid[o] ? results_.thickness[o]
                                            : std::numeric_limits<float>::quiet_NaN();
    }
    assembler_.push(encoders[k], line.data(), xray + size_t(k) * D);
  }
  if (observer_) observer_(results_, encoders, count);
}

void LaneProcessor::reconfigure(const LaneConfig& lane) {
  pipe_ = std::make_unique<LinePipeline>(std::vector<LaneConfig>{lane}, opt_.threads);
  lane_ = lane;
  assembler_.set_config(lane);
}

void LaneProcessor::push_missing(int64_t encoder) {
  assembler_.push_missing(encoder);
}

void LaneProcessor::restart(const std::string& reason) {
  assembler_.restart(reason);
}

void LaneProcessor::finish() {
  assembler_.flush();
}

}  // namespace rangex
