#include "offline/line_path.h"

#include "core/error.h"

namespace rangex {

namespace {
StageRunnerOptions offline_options(const BackendRequest& backend) {
  StageRunnerOptions o;
  o.backend = backend;
  o.verify_fraction = 0;
  o.fall_back = false;
  return o;
}
}  // namespace

LinePath::LinePath(const std::vector<LaneConfig>& lanes, const BackendRequest& backend)
    : runner_(
          lanes, offline_options(backend),
          [this](std::vector<QueuedLine>& lines, const LineResults& r, double ms) {
            finished(lines, r, ms);
          },
          [](std::vector<QueuedLine>& lines, const std::string& why) {
            fail(lines.size(), " lines lost: ", why);
          }) {
  for (const LaneConfig& l : lanes)
    lanes_[l.id].xray.resize(size_t(l.xray.pixels) * size_t(l.xray.energies));
}

void LinePath::attach(int lane_id, LaneProcessor* proc) {
  const auto it = lanes_.find(lane_id);
  if (it == lanes_.end()) fail("lane ", lane_id, " is not on this line path");
  it->second.proc = proc;
}

FusionStats LinePath::fusion(int lane_id) const {
  const auto it = lanes_.find(lane_id);
  return it == lanes_.end() ? FusionStats{} : it->second.fusion;
}

void LinePath::run(std::vector<QueuedLine>& lines, const Observer& observe) {
  if (lines.empty()) return;
  observe_ = &observe;
  runner_.launch(std::move(lines));
  runner_.finish_all();
  observe_ = nullptr;
  lines = std::move(done_);
  done_.clear();
}

void LinePath::finished(std::vector<QueuedLine>& lines, const LineResults& r, double ms) {
  stage_s_ += ms / 1e3;
  lanes_.at(lines.front().line.lane).fusion += r.fusion;
  if (observe_ && *observe_) (*observe_)(lines, r);
  for (size_t k = 0; k < lines.size(); ++k) {
    Lane& l = lanes_.at(lines[k].line.lane);
    if (!l.proc) fail("lane ", lines[k].line.lane, " has no processor on this line path");
    push_line_results(*l.proc, lines[k], r, k, lines.size(), l.xray);
  }
  done_ = std::move(lines);
}

void shape_block(std::vector<QueuedLine>& lines, int count, int lane_id, size_t frame_bytes,
                 int pixels) {
  lines.resize(size_t(count));
  for (QueuedLine& q : lines) {
    q.line.lane = lane_id;
    q.line.cam0.resize(frame_bytes);
    q.line.cam1.resize(frame_bytes);
    q.line.xray.resize(size_t(pixels) * sizeof(uint16_t));
    q.restart.clear();
  }
}

}  // namespace rangex
