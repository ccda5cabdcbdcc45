#include "service/shift_recorder.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>

#include "core/error.h"
#include "core/log.h"
#include "core/recording.h"
#include "core/size_limits.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {

constexpr size_t kQueueLines = 256;  // about 64 MB of 257 kB lines between ingest and the disk

int64_t steady_now() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string utc_name() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[40];
  std::strftime(b, sizeof b, "shift-%Y%m%dT%H%M%SZ", &tm);
  return b;
}

uint64_t line_bytes(const LaneConfig& l) {
  return 2 * uint64_t(l.frame_width) * uint64_t(l.frame_height) +
         2 * uint64_t(l.xray.pixels) * uint64_t(l.xray.energies) + 8;
}

}  // namespace

ShiftRecorder::ShiftRecorder(const PlantConfig& plant, std::string data_dir, double reserve_mb,
                             Audit audit)
    : plant_(plant),
      root_((fs::path(data_dir) / "recordings").string()),
      reserve_mb_(reserve_mb),
      audit_(std::move(audit)) {
  thread_ = std::thread([this] { run(); });
}

ShiftRecorder::~ShiftRecorder() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    stop_thread_ = true;  // the writer ends a running recording with what is queued
  }
  cv_.notify_all();
  thread_.join();
}

RecordingStatus ShiftRecorder::start(const RecordingRequest& req, double lines_per_s,
                                     const std::string& who) {
  std::vector<int> lanes = req.lanes;
  if (lanes.empty())
    for (const LaneConfig& l : plant_.lanes) lanes.push_back(l.id);
  std::sort(lanes.begin(), lanes.end());
  lanes.erase(std::unique(lanes.begin(), lanes.end()), lanes.end());
  uint64_t per_second = 0;
  uint64_t mask = 0;
  for (int id : lanes) {
    const LaneConfig& l = plant_.lane(id);  // NotFound for an unknown lane
    if (id >= 64) fail("lane ", id, ": recordings take lanes 0..63");
    mask |= uint64_t(1) << id;
    per_second += uint64_t(std::max(0.0, lines_per_s) * double(line_bytes(l)));
  }
  if (!(req.minutes > 0) || req.minutes > 24 * 60)
    fail("a recording lasts more than 0 and at most 1440 minutes (got ", req.minutes, ")");
  const std::string name = req.name.empty() ? utc_name() : req.name;
  check_name("a recording's name", name);
  if (name.find_first_of("/\\") != std::string::npos || name == "." || name == "..")
    fail("recording name '", name, "' is not a plain folder name");
  std::lock_guard<std::mutex> lk(mu_);
  if (status_.active)
    throw FailedPrecondition(join("recording '", status_.name, "' is running; stop it first"));
  const fs::path dir = fs::path(root_) / name;
  if (fs::exists(dir)) throw FailedPrecondition(join("recording '", name, "' exists already"));
  // The disk, checked before it starts: what its minutes take at the lanes' rate now must fit
  // in the free space less the store's reserve; it never writes more than that space.
  fs::create_directories(root_);
  std::error_code ec;
  const auto space = fs::space(root_, ec);
  if (ec) fail("the recordings' volume cannot be measured: ", ec.message());
  const double reserve = reserve_mb_ * 1048576.0;
  const uint64_t budget =
      double(space.available) > reserve ? uint64_t(double(space.available) - reserve) : 0;
  const uint64_t estimate = uint64_t(double(per_second) * req.minutes * 60);
  if (estimate > budget || budget == 0)
    throw FailedPrecondition(join(
        "recording refused: ", req.minutes, " minutes of ", lanes.size(), " lanes at ", lines_per_s,
        " lines/s take about ", estimate >> 20, " MB; the volume has ", space.available >> 20,
        " MB free and keeps ", uint64_t(reserve_mb_), " MB for the store"));
  for (int id : lanes) {
    const LaneConfig& l = plant_.lane(id);
    RecordingInfo info;
    info.lanes = {id};
    info.width = l.frame_width;
    info.height = l.frame_height;
    info.xray_pixels = l.xray.pixels;
    info.xray_energies = l.xray.energies;
    info.encoder_step_mm = l.encoder_step_mm;
    info.calibration_id = plant_.calibration_id;
    writers_[id] =
        std::make_unique<RecordingWriter>((dir / ("lane" + std::to_string(id))).string(), info);
  }
  status_ = RecordingStatus{};
  status_.active = true;
  status_.name = name;
  status_.dir = dir.string();
  status_.lanes = lanes;
  status_.minutes = req.minutes;
  status_.started_unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count();
  status_.budget_bytes = budget;
  status_.estimate_bytes = estimate;
  deadline_ns_ = steady_now() + int64_t(req.minutes * 60e9);
  lanes_mask_ = mask;
  std::string list;
  for (int id : lanes) list += (list.empty() ? "" : ",") + std::to_string(id);
  audit_(who, "recording.start",
         join(name, ": lanes ", list, ", ", req.minutes, " minutes, about ", estimate >> 20,
              " MB of ", budget >> 20, " MB free for it"));
  log::info("recording_start", "recording {} of lanes {} for {} minutes", name, list, req.minutes);
  return status_;
}

void ShiftRecorder::end(const std::string& who, const std::string& why) {
  lanes_mask_ = 0;
  status_.active = false;
  status_.ended = why;
  std::string error;
  for (auto& [id, w] : writers_) {
    try {
      w->close();
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  writers_.clear();
  if (!error.empty()) status_.ended += "; closing failed: " + error;
  audit_(who, "recording.end",
         join(status_.name, ": ", status_.ended, "; ", status_.lines, " lines, ",
              status_.bytes >> 20, " MB, ", status_.left_out, " lines left out"));
  log::info("recording_end", "recording {}: {} ({} lines)", status_.name, status_.ended,
            status_.lines);
}

RecordingStatus ShiftRecorder::stop(const std::string& who, const std::string& why) {
  std::unique_lock<std::mutex> lk(mu_);
  if (!status_.active) throw FailedPrecondition("no recording is running");
  // The writer ends it, after what is queued.
  stop_who_ = who;
  stop_why_ = why;
  cv_.notify_all();
  cv_.wait_for(lk, std::chrono::seconds(30), [this] { return !status_.active; });
  return status_;
}

RecordingStatus ShiftRecorder::status() const {
  std::lock_guard<std::mutex> lk(mu_);
  return status_;
}

bool ShiftRecorder::wants(int lane) const {
  return lane >= 0 && lane < 64 && (lanes_mask_.load() >> lane & 1u);
}

ShiftRecorder::Line ShiftRecorder::copy(const IncomingLine& in) {
  Line l;
  l.lane = in.lane;
  l.encoder = in.encoder;
  l.cam0.assign(in.cam0.data(), in.cam0.size());
  l.cam1.assign(in.cam1.data(), in.cam1.size());
  l.xray.assign(in.xray.data(), in.xray.size());
  l.xray_high.assign(in.xray_high.data(), in.xray_high.size());
  return l;
}

void ShiftRecorder::offer(Line&& l) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!status_.active || !writers_.count(l.lane)) return;
    if (queue_.size() >= kQueueLines) {
      ++status_.left_out;
      return;
    }
    queue_.push_back(std::move(l));
  }
  cv_.notify_all();
}

void ShiftRecorder::run() {
  std::unique_lock<std::mutex> lk(mu_);
  while (true) {
    cv_.wait_for(lk, std::chrono::milliseconds(200),
                 [this] { return stop_thread_ || !queue_.empty() || !stop_why_.empty(); });
    std::deque<Line> batch;
    batch.swap(queue_);
    // The files are written without the lock: ingest's offer() never waits for the disk.
    // Only this thread touches the writers while a recording runs.
    lk.unlock();
    std::string failed;
    uint64_t lines = 0, bytes = 0;
    bool full = false;
    const uint64_t room = [&] {
      std::lock_guard<std::mutex> g(mu_);
      return status_.active ? status_.budget_bytes - std::min(status_.budget_bytes, status_.bytes)
                            : 0;
    }();
    for (const Line& l : batch) {
      const auto w = writers_.find(l.lane);
      if (room == 0 || w == writers_.end() || !failed.empty() || full) break;
      const uint64_t n = l.cam0.size() + l.cam1.size() + l.xray.size() + l.xray_high.size() + 8;
      if (bytes + n > room) {
        full = true;
        break;
      }
      try {
        w->second->append(
            l.lane, {reinterpret_cast<const uint8_t*>(l.cam0.data()),
                     reinterpret_cast<const uint8_t*>(l.cam1.data()),
                     reinterpret_cast<const uint16_t*>(l.xray.data()), l.encoder,
                     l.xray_high.empty() ? nullptr
                                         : reinterpret_cast<const uint16_t*>(l.xray_high.data())});
      } catch (const std::exception& e) {
        failed = e.what();
        break;
      }
      ++lines;
      bytes += n;
    }
    lk.lock();
    status_.lines += lines;
    status_.bytes += bytes;
    if (status_.active) {
      if (!failed.empty())
        end("rangexd", "writing failed: " + failed);
      else if (full)
        end("rangexd", "it wrote the space it was given");
      // What came in meanwhile goes in before a stop.
      else if (!stop_why_.empty() && queue_.empty())
        end(stop_who_, stop_why_);
      else if (steady_now() >= deadline_ns_)
        end("rangexd", "its minutes are up");
      else if (stop_thread_ && queue_.empty())
        end("rangexd", "the server stopped");
    }
    if (!status_.active) {
      stop_who_.clear();
      stop_why_.clear();
    }
    cv_.notify_all();  // stop() waits for the end
    if (stop_thread_ && queue_.empty()) break;
  }
}

}  // namespace rangex
