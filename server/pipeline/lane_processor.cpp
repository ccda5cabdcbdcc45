#include "pipeline/lane_processor.h"

#include <chrono>
#include <limits>

namespace rangex {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

InspectedFillet inspect_image(FilletImage&& img, const InspectionParams& p,
                              const LaneProcessorOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  InspectedFillet f;
  f.result = inspect_fillet(img, p, opt.keep_images);
  // The statistics' images serve the evaluation's own inspections (offline/fragment_chance.h),
  // never a lane's results: not held while the fillet is handled and stored.
  f.result.round_stat = {}, f.result.needle_stat = {};
  if (opt.baseline) f.baseline = inspect_fillet_xray_only(img, p, false);
  if (!opt.keep_images) {
    img.xray.clear();
    img.thickness.clear();
    img.mask.clear();
  }
  f.image = std::move(img);
  f.inspect_ms = 1e3 * since(t0);
  return f;
}

LaneProcessor::LaneProcessor(const LaneConfig& lane, LaneProcessorOptions opt, FilletSink sink,
                             ImageSink images)
    : lane_(lane),
      opt_(opt),
      sink_(std::move(sink)),
      images_(std::move(images)),
      assembler_(lane,
                 [this](FilletImage&& img) {
                   if (images_) return images_(std::move(img));
                   InspectedFillet f = inspect_image(std::move(img), lane_.inspection, opt_);
                   inspect_s_ += f.inspect_ms / 1e3;
                   sink_(std::move(f));
                 }),
      line_(size_t(lane.xray.pixels)) {}

void LaneProcessor::push(const float* thickness, const uint8_t* valid, const uint16_t* xray,
                         int64_t encoder, bool blind, const uint16_t* xray_high) {
  const int D = lane_.xray.pixels;
  for (int i = 0; i < D; ++i)
    line_[i] = valid[i] && !blind ? thickness[i] : std::numeric_limits<float>::quiet_NaN();
  assembler_.push(encoder, line_.data(), xray, xray_high);
}

bool LaneProcessor::blind(const uint8_t* profile_valid, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (profile_valid[i]) return false;
  return true;
}

void LaneProcessor::push(const LineResults& r, int first, int count, const uint16_t* xray,
                         const int64_t* encoders) {
  const size_t D = size_t(lane_.xray.pixels);
  const size_t lines = r.thickness.size() / D;
  const size_t G = lines ? r.profile_valid.size() / lines : 0;
  for (int k = 0; k < count; ++k) {
    const size_t o = size_t(first + k) * D;
    const bool b = G > 0 && blind(&r.profile_valid[size_t(first + k) * G], G);
    push(&r.thickness[o], &r.thickness_valid[o], xray + size_t(k) * D, encoders[k], b);
  }
}

void LaneProcessor::reconfigure(const LaneConfig& lane) {
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
