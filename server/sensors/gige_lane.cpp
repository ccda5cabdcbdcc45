#include "sensors/gige_lane.h"

#include <algorithm>
#include <chrono>

#include "core/error.h"
#include "core/log.h"
#include "sensors/frame_counts.h"

namespace rangex {

namespace {

DeviceSetup setup_of(const LaneConfig& lane, int index, int buffers) {
  const SensorSources& s = lane.sources;
  DeviceSetup d;
  d.id = s.devices()[size_t(index)];
  d.role = index < 2 ? DeviceRole::kCamera : DeviceRole::kXray;
  d.width = d.role == DeviceRole::kXray ? lane.xray.pixels : lane.frame_width;
  // A dual-energy detector sends both layers' lines as the two rows of one frame: low, high.
  d.height = d.role == DeviceRole::kXray ? std::max(1, lane.xray.energies) : lane.frame_height;
  d.trigger = s.trigger;
  d.trigger_line = s.trigger_line;
  d.offset_y = d.role == DeviceRole::kXray ? -1 : s.offset_y;
  d.exposure_us = d.role == DeviceRole::kXray ? 0 : s.exposure_us;
  d.packet_size = s.packet_size;
  d.buffers = buffers;
  return d;
}

}  // namespace

GigeLane::GigeLane(const LaneConfig& lane, LaneSink sink, SensorOptions opt)
    : lane_(lane.id),
      config_(lane),
      sink_(std::move(sink)),
      opt_(opt),
      joiner_([this](int64_t count, std::array<LineBytes, kLaneDevices>&& f) {
        IncomingLine in;
        in.lane = lane_;
        in.encoder = count;
        in.cam0 = std::move(f[0]);
        in.cam1 = std::move(f[1]);
        if (config_.xray.energies == 2) {
          // Row 1 of the X-ray frame is the high layer's line (a copy of 2 bytes a pixel);
          // row 0 stays where the device put it.
          const size_t row = f[2].size() / 2;
          in.xray_high.assign(f[2].data() + row, row);
          f[2].truncate(row);
        }
        in.xray = std::move(f[2]);
        if (!sink_.line(std::move(in))) ++refused_;
      }) {
  if (!lane.sources.enabled()) fail("lane ", lane.id, " has no sources");
  const std::vector<std::string> ids = lane.sources.devices();
  for (int i = 0; i < kLaneDevices; ++i) {
    SensorState s;
    s.role = role_name(i < 2 ? DeviceRole::kCamera : DeviceRole::kXray, i);
    s.device = ids[size_t(i)];
    states_.push_back(s);
  }
  for (int i = 0; i < kLaneDevices; ++i) threads_.emplace_back([this, i] { run_device(i); });
}

GigeLane::~GigeLane() {
  stop();
}

void GigeLane::stop() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_)
    if (t.joinable()) t.join();
}

void GigeLane::set(int index, const std::function<void(SensorState&)>& change) {
  std::lock_guard<std::mutex> lk(mu_);
  change(states_[size_t(index)]);
}

bool GigeLane::sleep_for(double seconds) {
  std::unique_lock<std::mutex> lk(mu_);
  wake_.wait_for(lk, std::chrono::duration<double>(seconds), [this] { return stop_.load(); });
  return !stop_;
}

void GigeLane::run_device(int index) {
  using Clock = std::chrono::steady_clock;
  const DeviceSetup setup = setup_of(config_, index, opt_.buffers);
  const std::string who =
      join("lane ", lane_, " ", states_[size_t(index)].role, " (", setup.id, ")");
  double backoff = opt_.backoff_min_s;
  bool first = true, streamed_before = false;
  while (!stop_) {
    set(index, [&](SensorState& s) {
      s.state = "connecting";
      if (!first) ++s.reconnects;
    });
    first = false;
    bool streamed = false;
    auto started = Clock::now();
    try {
      GigeDevice dev(setup);
      // Where the lane stood once this session's acquisition had started: a frame of ours
      // cannot be in the joiner yet.
      const std::optional<int64_t> newest_at_start = joiner_.newest();
      set(index, [&](SensorState& s) {
        s.state = "streaming";
        s.description = dev.description();
      });
      log::info("sensor_streaming", "{}: {} streaming", who, dev.description());
      streamed = true;
      started = Clock::now();
      auto heard = Clock::now();
      std::string why;
      DeviceFrame frame;
      bool first_frame = true;
      int64_t offset = 0;        // the session's count to the lane's
      bool own_count = false;    // started with the lane, counting its own frames
      bool wrong_named = false;  // this session's first wrong-format frame logged
      while (!stop_) {
        const GigeDevice::Got got = dev.next(100, frame, why);
        const DeviceStreamCounts sc = dev.stream_counts();
        if (got == GigeDevice::Got::kNothing) {
          const double silent = std::chrono::duration<double>(Clock::now() - heard).count();
          if (silent > opt_.silence_probe_s) {
            if (!dev.answering()) fail("stopped answering after ", int(silent), " s of silence");
            heard = Clock::now();
          }
          continue;
        }
        heard = Clock::now();
        set(index, [&](SensorState& s) {
          s.underruns = sc.underruns;
          if (got == GigeDevice::Got::kIncomplete) ++s.incomplete;
          if (got == GigeDevice::Got::kWrongFormat) {
            if (s.wrong_format++ == 0) s.error = why;
          }
          if (got == GigeDevice::Got::kFrame) {
            ++s.frames;
            s.lost_frames += frame.lost_before;
          }
        });
        // Named once a session: a device reconfigured by another tool, or packets of another
        // device on this stream's port.
        if (got == GigeDevice::Got::kWrongFormat && !wrong_named) {
          wrong_named = true;
          log::warn("sensor_wrong_format", "{}: {}", who, why);
        }
        if (got != GigeDevice::Got::kFrame) continue;
        std::lock_guard<std::mutex> lk(count_mu_);
        // A device counting its own frames starts again at 1 each session (frame_counts.h).
        if (first_frame && !frame.from_encoder) {
          offset = session_count_offset(streamed_before, newest_at_start, joiner_.newest(),
                                        frame.count, joiner_.window());
          own_count = keeps_own_count(streamed_before, newest_at_start, joiner_.window());
          if (own_count) note_first_id(index, who, frame.id);
        }
        first_frame = false;
        const int64_t shift = own_count ? start_ids_.shift(index) : 0;
        joiner_.add(index, frame.count + offset + shift, std::move(frame.bytes));
      }
      set(index, [](SensorState& s) { s.state = "stopped"; });
      return;
    } catch (const std::exception& e) {
      streamed_before = streamed_before || streamed;
      const std::string reason = e.what();
      set(index, [&](SensorState& s) {
        s.state = streamed ? "lost" : "refused";
        s.error = reason;
      });
      if (streamed) {
        log::warn("sensor_lost", "{}: {}", who, reason);
        sink_.lost(join(who, " dropped off: ", reason));
      } else {
        log::warn("sensor_refused", "{}: {}", who, reason);
      }
    }
    // A session that ran a while starts the backoff afresh.
    if (streamed && std::chrono::duration<double>(Clock::now() - started).count() > 10)
      backoff = opt_.backoff_min_s;
    if (!sleep_for(backoff)) break;
    backoff = std::min(opt_.backoff_max_s, backoff * 2);
  }
  set(index, [](SensorState& s) { s.state = "stopped"; });
}

void GigeLane::note_first_id(int index, const std::string& who, uint64_t id) {
  const bool moved = start_ids_.first(index, id);
  if (moved) {
    // The devices that delivered first had lost frames before theirs: the partial lines
    // hold counts that are now wrong (none was emitted: the lane waits for every device).
    joiner_.reset();
  }
  for (int d = 0; d < kLaneDevices; ++d) {
    const int64_t k = start_ids_.shift(d);
    if (k != 0 && (d == index || moved))
      log::warn("sensor_start_frames_lost",
                "lane {} {}: its first frame id is {} past the lane's first: that many frames "
                "were lost before it reached rangexd, and its count starts that many on",
                lane_, states_[size_t(d)].role, k);
  }
  log::info("sensor_first_frame", "{}: first frame id {}", who, id);
}

LaneSensors GigeLane::state() const {
  LaneSensors l;
  l.lane = lane_;
  l.trigger = trigger_name(config_.sources.trigger);
  const JoinerStats j = joiner_.stats();
  l.lines = j.lines;
  l.incomplete = j.incomplete;
  l.refused = refused_;
  std::lock_guard<std::mutex> lk(mu_);
  l.devices = states_;
  for (size_t i = 0; i < l.devices.size(); ++i) {
    l.devices[i].lacked = j.lacked[i];
    l.devices[i].stale = j.stale[i];
  }
  return l;
}

}  // namespace rangex
