#include "backends/stage_runner.h"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "backends/verify.h"
#include "core/error.h"
#include "core/log.h"

namespace rangex {

namespace {
bool same_shape(const LaneConfig& a, const LaneConfig& b) {
  return a.frame_width == b.frame_width && a.frame_height == b.frame_height &&
         a.fusion.grid_samples == b.fusion.grid_samples && a.xray.pixels == b.xray.pixels;
}
}  // namespace

StageRunner::StageRunner(const std::vector<LaneConfig>& lanes, StageRunnerOptions opt, Sink sink,
                         Lost lost)
    : opt_(std::move(opt)), sink_(std::move(sink)), lost_(std::move(lost)) {
  if (lanes.empty()) fail("the line stages need at least one lane");
  std::vector<std::vector<LaneConfig>> configs;
  for (const LaneConfig& l : lanes) {
    size_t g = 0;
    while (g < configs.size() && !same_shape(configs[g].front(), l)) ++g;
    if (g == configs.size()) {
      configs.emplace_back();
      groups_.emplace_back();
      groups_[g].frame_bytes = size_t(l.frame_width) * size_t(l.frame_height);
      groups_[g].pixels = size_t(l.xray.pixels);
    }
    where_[l.id] = {int(g), int(configs[g].size())};
    configs[g].push_back(l);
    groups_[g].lane_ids.push_back(l.id);
  }
  BackendRequest cpu_req = opt_.backend;
  cpu_req.name = "cpu";
  cpu_req.fail_after = cpu_req.corrupt_after = -1;
  std::string why;
  for (size_t g = 0; g < groups_.size(); ++g) {
    Group& gr = groups_[g];
    gr.cpu = create_backend(cpu_req);
    gr.cpu->set_lanes(configs[g]);
    gr.active = gr.cpu.get();
    if (!note_.empty() && running_.reference) continue;  // the first group fell back already
    try {
      std::unique_ptr<Backend> b = create_backend(opt_.backend, &why);
      if (!b->info().reference) {
        b->set_lanes(configs[g]);
        gr.device = std::move(b);
        gr.active = gr.device.get();
      }
      if (g == 0) note_ = why.empty() ? "requested" : why;
    } catch (const std::exception& e) {
      if (!opt_.fall_back) throw;
      // Loud, and the plant keeps inspecting on the CPU.
      note_ = "backend '" + opt_.backend.name + "' cannot start: " + e.what() + "; running on cpu";
      log::error("backend_unavailable", "{}", note_);
      for (Group& earlier : groups_)
        if (earlier.device) {
          earlier.failed.push_back(std::move(earlier.device));
          earlier.active = earlier.cpu.get();
        }
    }
    running_ = groups_.front().active->info();
  }
}

StageRunner::~StageRunner() = default;

BackendInfo StageRunner::running() const {
  std::lock_guard<std::mutex> lock(info_mu_);
  return running_;
}

std::string StageRunner::note() const {
  std::lock_guard<std::mutex> lock(info_mu_);
  return note_;
}

StageRunnerStats StageRunner::stats() const {
  return {batches_.load(), verified_.load(), mismatches_.load(), failures_.load(),
          bytes_staged_.load()};
}

size_t StageRunner::in_flight(int group) const {
  size_t n = 0;
  for (const InFlight& f : inflight_) n += f.group == group;
  return n;
}

void StageRunner::launch(std::vector<QueuedLine>&& lines) {
  if (lines.empty()) return;
  // One batch per group; with one group (the usual plant) the batch goes whole.
  std::vector<std::vector<QueuedLine>> parts(groups_.size());
  if (groups_.size() == 1) {
    parts[0] = std::move(lines);
  } else {
    for (QueuedLine& q : lines) parts[where_.at(q.line.lane).first].push_back(std::move(q));
  }
  for (size_t g = 0; g < parts.size(); ++g) {
    if (parts[g].empty()) continue;
    Group& gr = groups_[g];
    // Batches submitted to a backend that has since failed go first (recomputed on the CPU
    // while its staging slots are free), then at most two in flight.
    while (!inflight_.empty() &&
           inflight_.front().backend != groups_[inflight_.front().group].active)
      finish_oldest();
    while (in_flight(int(g)) >= 2) finish_oldest();
    InFlight f;
    f.group = int(g);
    f.lines = std::move(parts[g]);
    f.launched = std::chrono::steady_clock::now();
    try {
      submit(gr, f);
    } catch (const std::exception& e) {
      if (gr.active == gr.cpu.get()) {
        lost_(f.lines, std::string("line stages failed on the CPU: ") + e.what());
        continue;
      }
      fail_over(e.what());
      f.backend = nullptr;  // recomputed on the CPU, with every batch in flight before it
      inflight_.push_back(std::move(f));
      finish_all();
      continue;
    }
    inflight_.push_back(std::move(f));
    if (!gr.active->info().overlaps) finish_all();  // computes inside collect()
  }
}

LineBatchSlot& StageRunner::fill(Group& g, Backend& b, const std::vector<QueuedLine>& lines) {
  const int n = int(lines.size());
  LineBatchSlot& s = b.acquire(n);
  uint8_t* frames = s.frames();
  int32_t* slots = s.lane_slot();
  for (int k = 0; k < n; ++k) {
    const IncomingLine& in = lines[k].line;
    // The engine checked the sizes at admission; this is the one copy of each frame.
    std::memcpy(frames + g.frame_bytes * (2 * size_t(k)), in.cam0.data(), g.frame_bytes);
    std::memcpy(frames + g.frame_bytes * (2 * size_t(k) + 1), in.cam1.data(), g.frame_bytes);
    slots[k] = where_.at(in.lane).second;
  }
  s.lines = n;
  bytes_staged_ += 2 * g.frame_bytes * size_t(n);
  return s;
}

void StageRunner::submit(Group& g, InFlight& f) {
  LineBatchSlot& s = fill(g, *g.active, f.lines);
  g.active->submit(s);
  f.backend = g.active;
  f.slot = &s;
}

bool StageRunner::compute_on_cpu(Group& g, InFlight& f, LineResults& out) {
  try {
    LineBatchSlot& s = fill(g, *g.cpu, f.lines);
    g.cpu->submit(s);
    g.cpu->collect(s, out);
    return true;
  } catch (const std::exception& e) {
    lost_(f.lines, std::string("line stages failed on the CPU: ") + e.what());
    return false;
  }
}

void StageRunner::finish_oldest() {
  InFlight f = std::move(inflight_.front());
  inflight_.pop_front();
  Group& g = groups_[f.group];
  bool ok = false;
  results_.fusion = {};  // a batch's own counts (backends add to them)
  if (f.backend && f.backend == g.active) {
    try {
      g.active->collect(*f.slot, results_);
      ok = true;
    } catch (const std::exception& e) {
      if (g.active == g.cpu.get()) {
        lost_(f.lines, std::string("line stages failed on the CPU: ") + e.what());
        return;
      }
      fail_over(e.what());
    }
  }
  if (!ok) {
    // Submitted to a backend that has since failed: its results are not to be trusted.
    if (!compute_on_cpu(g, f, results_)) return;
  } else if (g.active != g.cpu.get() && verify_now()) {
    verify(g, f, results_);
  }
  ++batches_;
  sink_(f.lines, results_,
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f.launched)
            .count());
}

void StageRunner::finish_all() {
  while (!inflight_.empty()) finish_oldest();
}

bool StageRunner::verify_now() {
  if (opt_.verify_fraction <= 0) return false;
  verify_credit_ += opt_.verify_fraction;
  if (verify_credit_ < 1) return false;
  verify_credit_ -= 1;
  return true;
}

void StageRunner::verify(Group& g, InFlight& f, LineResults& r) {
  // The staging still holds the batch's frames: collect() does not touch them.
  reference_.fusion = {};
  try {
    run_batch(*g.cpu, f.slot->frames(), int(f.lines.size()), f.slot->lane_slot(), reference_);
  } catch (const std::exception& e) {
    log::error("verification_failed", "verification on the CPU failed: {}", e.what());
    return;
  }
  ++verified_;
  const auto m = compare_line_results(r, reference_, int(f.lines.size()));
  if (!m) return;
  ++mismatches_;
  const IncomingLine& in = f.lines.at(std::min(m->line, f.lines.size() - 1)).line;
  log::error("backend_mismatch",
             "backend {} differs from the CPU reference: {} (lane {}, encoder {}); this batch is "
             "decided from the CPU's results",
             g.active->info().name, m->describe(), in.lane, in.encoder);
  std::swap(r, reference_);
}

void StageRunner::fail_over(const std::string& why) {
  ++failures_;
  std::string name;
  for (Group& g : groups_) {
    if (!g.device) continue;
    name = g.device->info().name;
    g.failed.push_back(std::move(g.device));
    g.active = g.cpu.get();
  }
  std::lock_guard<std::mutex> lock(info_mu_);
  note_ = "backend " + name + " failed: " + why + "; switched to cpu";
  running_ = groups_.front().active->info();
  log::error("backend_failed",
             "{} (the batches in flight are recomputed on the CPU, no line is lost)", note_);
}

void StageRunner::update_lane(int lane_id, const LaneConfig& lane) {
  finish_all();
  const auto [g, slot] = where_.at(lane_id);
  Group& gr = groups_[g];
  gr.cpu->update_lane(slot, lane);
  if (!gr.device) return;
  try {
    gr.device->update_lane(slot, lane);
  } catch (const std::exception& e) {
    fail_over(std::string("updating lane tables: ") + e.what());
  }
}

void push_line_results(LaneProcessor& proc, const QueuedLine& q, const LineResults& r, size_t k,
                       size_t batch_lines, std::vector<uint16_t>& xray) {
  const size_t D = q.line.xray.size() / sizeof(uint16_t);
  // A dual-energy lane's high line goes into the buffer's second half (admission and
  // replay checked the sizes against the lane's energies).
  const bool dual = !q.line.xray_high.empty();
  if (xray.size() < D * (dual ? 2 : 1))
    fail("lane ", q.line.lane, ": a line of ", dual ? 2 : 1, " X-ray lines of ", D,
         " pixels for a buffer of ", xray.size());
  std::memcpy(xray.data(), q.line.xray.data(), D * sizeof(uint16_t));
  if (dual) std::memcpy(xray.data() + D, q.line.xray_high.data(), D * sizeof(uint16_t));
  const size_t G = r.profile_valid.size() / std::max<size_t>(1, batch_lines);
  const bool blind = G > 0 && LaneProcessor::blind(&r.profile_valid[k * G], G);
  proc.push(&r.thickness[k * D], &r.thickness_valid[k * D], xray.data(), q.line.encoder, blind,
            dual ? xray.data() + D : nullptr);
}

}  // namespace rangex
