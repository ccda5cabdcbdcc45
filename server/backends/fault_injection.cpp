#include "backends/fault_injection.h"

#include "backends/backend_error.h"

namespace rangex {

FaultInjectingBackend::FaultInjectingBackend(std::unique_ptr<Backend> inner, FaultPlan plan)
    : inner_(std::move(inner)), info_(inner_->info()), plan_(plan) {
  // Not the reference any more: the server verifies it and falls back from it.
  info_.name += "+faults";
  info_.reference = false;
}

void FaultInjectingBackend::set_lanes(const std::vector<LaneConfig>& lanes) {
  inner_->set_lanes(lanes);
  lanes_ = lanes;
}

void FaultInjectingBackend::update_lane(int slot, const LaneConfig& lane) {
  inner_->update_lane(slot, lane);
  lanes_.at(slot) = lane;
}

void FaultInjectingBackend::collect(LineBatchSlot& batch, LineResults& out) {
  const int n = collected_++;
  if (plan_.fail_after >= 0 && n >= plan_.fail_after) {
    LineResults discard;
    inner_->collect(batch, discard);  // the slot comes back; its results are lost
    throw BackendError(inner_->info().name + ": injected failure (device lost) at batch " +
                       std::to_string(n));
  }
  inner_->collect(batch, out);
  times_ = inner_->last_times();
  if (plan_.corrupt_after >= 0 && n >= plan_.corrupt_after)
    for (size_t i = 0; i < out.thickness.size(); ++i)
      if (out.thickness_valid[i]) out.thickness[i] += 1.0f;
}

}  // namespace rangex
