// bench-gige: a lane over GigE Vision against the replay of the same recording, in one run.
// The lane's three fake devices run in a process of their own (`fake-lane`), so that
// this process's CPU time is rangexd's alone: the GigE path (receive threads, joining,
// admission, line stages, assembly, inspection, the store) per line, against the replay's
// (line stages, assembly, inspection) per line. The fakes are paced by their trigger poll,
// so lines/s over GigE says what they sent; the CPU time per line says what rangexd can take.
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "args.h"
#include "bench/bench_commands.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"
#include "offline/replay.h"
#include "service/server.h"
#include "sim/plant_simulator.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         double(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
}

std::string read_text(const char* path) {
  std::ifstream f(path);
  std::string s;
  std::getline(f, s);
  return s;
}

bool write_text(const char* path, const std::string& v) {
  std::ofstream f(path);
  f << v << "\n";
  return bool(f);
}

}  // namespace

int cmd_bench_gige(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"config", "fillets", "seed", "period-us", "packet-size"});
  a.expect_positionals(0,
                       "bench-gige [--fillets 3] [--seed 5] [--period-us 2000] [--packet-size B]");
  PlantConfig plant = load_config(a.get("config", ""));
  plant.lanes.resize(1);
  plant.plc = {};
  const LaneConfig& lane = plant.lanes[0];
  const fs::path dir =
      fs::temp_directory_path() / ("rangex-bench-gige-" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  sim::SimulationParams sp;
  sp.lanes = 1;
  sp.scene.fillets = int(a.integer("fillets", 3));
  sp.seed = uint64_t(a.integer("seed", 5));
  sim::simulate_recording(plant, sp, (dir / "rec").string());
  const RecordingReader rec((dir / "rec").string());
  const int64_t lines = rec.info().lines;

  // The replay: the same lines through the line path, one CPU thread, no images; three
  // times, the median kept (a single replay of a few thousand lines varies by a third
  // between runs on a shared host).
  ReplayOptions ro;
  ro.backend = cpu_request(1);
  ro.keep_images = false;
  ro.baseline = false;
  std::vector<std::pair<double, double>> replays;  // CPU s, wall s
  for (int k = 0; k < 3; ++k) {
    const double c0 = cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    (void)replay_recording(rec, plant, ro);
    replays.emplace_back(
        cpu_seconds() - c0,
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(replays.begin(), replays.end());
  const double replay_cpu = replays[1].first, replay_wall = replays[1].second;

  // The socket buffers as docs/sensors.md says, while the bench runs (root only).
  const char* rmem = "/proc/sys/net/core/rmem_max";
  const std::string rmem_was = read_text(rmem);
  const bool raised = write_text(rmem, "33554432");
  const std::string rmem_now = read_text(rmem);

  // The fakes, in their own process: this program's `fake-lane` (rangexctl's command).
  const std::string period = std::to_string(a.integer("period-us", 2000));
  const pid_t fakes = fork();
  if (fakes == 0) {
    execl("/proc/self/exe", argv[0], "fake-lane", (dir / "rec").c_str(), "--addresses",
          "127.0.0.2,127.0.0.3,127.0.0.4", "--period-us", period.c_str(), "--lead", "100",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  plant.lanes[0].sources.cameras = {"127.0.0.2", "127.0.0.3"};
  plant.lanes[0].sources.xray = "127.0.0.4";
  plant.lanes[0].sources.trigger = LineTrigger::kEncoder;
  plant.lanes[0].sources.trigger_line = "Software";
  // Jumbo packets, as docs/sensors.md says (0: what the devices negotiate).
  plant.lanes[0].sources.packet_size = int(a.integer("packet-size", 8192));
  ServerOptions so;
  so.listen = "127.0.0.1:0";
  so.data_dir = (dir / "data").string();
  so.engine.backend = cpu_request(1);
  so.engine.images = false;
  double gige_cpu = 0, gige_wall = 0;
  uint64_t measured = 0;
  EngineStats stats;
  LaneSensors sensors;
  {
    RangexServer server(plant, so);
    auto processed = [&] { return server.engine().lane_state(lane.id).processed; };
    // From the 100th line on (the devices connected, the lead passed) to the recording's end.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
    while (processed() < 100 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const uint64_t p0 = processed();
    const double c0 = cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    while (processed() < p0 + uint64_t(lines) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    gige_cpu = cpu_seconds() - c0;
    gige_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    measured = processed() - p0;
    stats = server.engine().stats();
    const auto s = server.sensors();
    if (!s.empty()) sensors = s[0];
  }
  kill(fakes, SIGTERM);
  waitpid(fakes, nullptr, 0);
  if (raised) write_text(rmem, rmem_was);
  fs::remove_all(dir);
  if (measured == 0) fail("no line came over GigE Vision within 5 minutes (see the log above)");

  const double replay_us = 1e6 * replay_cpu / double(lines);
  const double gige_us = 1e6 * gige_cpu / double(measured);
  std::printf("bench-gige: one lane, %lld lines (%d fillets), CPU backend on one thread\n",
              (long long)lines, sp.scene.fillets);
  std::printf("  replay          %8.1f us CPU a line, %8.0f lines/s (median of 3; %.1f-%.1f us)\n",
              replay_us, double(lines) / replay_wall, 1e6 * replays[0].first / double(lines),
              1e6 * replays[2].first / double(lines));
  std::printf(
      "  GigE Vision     %8.1f us CPU a line, %8.0f lines/s as the fakes sent them "
      "(trigger poll %s us)\n",
      gige_us, double(measured) / gige_wall, period.c_str());
  std::printf(
      "  ratio           %8.2f  (replay's CPU a line over GigE's: the lines/s rangexd "
      "takes over GigE against replay, per core)\n",
      replay_us / gige_us);
  const double per = double(std::max<uint64_t>(1, stats.processed));
  std::printf(
      "  bytes copied a line on the server: %.0f parsed out of messages, %.0f into "
      "staging, %.0f of X-ray into the assembly\n",
      double(stats.bytes_parsed) / per, double(stats.batches.bytes_staged) / per,
      double(stats.bytes_xray_copied) / per);
  std::printf("  sensors: %llu lines, %llu missing; GVSP packets of %d bytes; rmem_max %s (%s)\n",
              (unsigned long long)sensors.lines, (unsigned long long)sensors.incomplete,
              plant.lanes[0].sources.packet_size, rmem_now.c_str(),
              raised ? "raised for the run" : "as it was: not root");
  return 0;
}

}  // namespace rangex::cli
