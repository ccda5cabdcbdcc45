// bench-server: lines/s end to end through gRPC on loopback for 1, 4 and 16 lanes, and the
// latency from a fillet's last line to its decision, each beside the in-process pipeline
// (LaneProcessor, no gRPC, no store) on the same lines in the same run.
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "feeder.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/server.h"
#include "sim/plant_simulator.h"

namespace rangex::cli {

namespace pb = rangex::v1;

namespace {
// One lane's lines, already rendered, sent as lane `lane`.
class MemorySource : public LineSource {
 public:
  MemorySource(const std::vector<pb::LineScan>& scans, int lane) : scans_(scans), lane_(lane) {}
  std::vector<int> lanes() const override { return {lane_}; }
  int64_t lines() const override { return int64_t(scans_.size()); }
  void line(int, int64_t n, pb::LineScan& out) override {
    out = scans_[size_t(n)];
    out.set_lane(lane_);
  }

 private:
  const std::vector<pb::LineScan>& scans_;
  int lane_;
};
}  // namespace

int cmd_bench_server(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"lines", "threads"});
  a.expect_positionals(0, "bench-server [--lines N]");
  const int n = int(a.integer("lines", 1200));
  const int threads =
      int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
  PlantConfig plant = default_plant_config(16);
  const LaneConfig& lc = plant.lanes[0];
  // One lane's worth of lines with fillets in them, reused on every lane.
  sim::SimulationParams sp;
  sp.scene.fillets = 3;
  sp.scene.lead_in_mm = 10;
  const sim::LaneSimulator sim(lc, sp);
  const int lines = int(std::min<int64_t>(n, sim.lines()));
  const size_t frame = size_t(lc.frame_width) * lc.frame_height;
  std::vector<pb::LineScan> scans(lines);
  for (int k = 0; k < lines; ++k) {
    std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(lc.xray.pixels) * 2, '\0');
    sim.render(k, reinterpret_cast<uint8_t*>(c0.data()), reinterpret_cast<uint8_t*>(c1.data()),
               reinterpret_cast<uint16_t*>(x.data()), nullptr, nullptr, nullptr);
    scans[k].set_encoder(sim.encoder(k));
    scans[k].set_cam0(std::move(c0));
    scans[k].set_cam1(std::move(c1));
    scans[k].set_xray(std::move(x));
  }
  std::printf(
      "end to end through gRPC on loopback, %d lines per lane (%d fillets each), %d threads\n",
      lines, sp.scene.fillets, threads);
  std::printf("%-6s %16s %16s %8s %24s\n", "lanes", "in-process l/s", "gRPC l/s", "ratio",
              "last line -> decision");
  for (int nl : {1, 4, 16}) {
    // In-process: the same lines through each lane's LaneProcessor, batches of 64.
    std::vector<uint8_t> frames(frame * 2 * 64);
    std::vector<uint16_t> xray(size_t(lc.xray.pixels) * 64);
    std::vector<int64_t> enc(64);
    const auto t0 = std::chrono::steady_clock::now();
    for (int lane = 0; lane < nl; ++lane) {
      LaneProcessor proc(plant.lanes[lane], {threads, false, false}, [](InspectedFillet&&) {});
      for (int k0 = 0; k0 < lines; k0 += 64) {
        const int c = std::min(64, lines - k0);
        for (int k = 0; k < c; ++k) {
          std::memcpy(&frames[frame * 2 * k], scans[k0 + k].cam0().data(), frame);
          std::memcpy(&frames[frame * (2 * k + 1)], scans[k0 + k].cam1().data(), frame);
          std::memcpy(&xray[size_t(lc.xray.pixels) * k], scans[k0 + k].xray().data(),
                      scans[k0 + k].xray().size());
          enc[k] = scans[k0 + k].encoder();
        }
        proc.push(c, frames.data(), xray.data(), enc.data());
      }
      proc.finish();
    }
    const double inproc =
        double(nl) * lines /
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // Through the server: one stream per lane, all at once.
    const std::string dir =
        (std::filesystem::temp_directory_path() /
         ("rangex-bench-" + std::to_string(getpid()) + "-" + std::to_string(nl)))
            .string();
    std::filesystem::remove_all(dir);
    PlantConfig pl = plant;
    pl.lanes.resize(nl);
    ServerOptions so;
    so.listen = "127.0.0.1:0";
    so.data_dir = dir;
    so.engine.threads = threads;
    so.engine.queue_lines = 4096;
    double grpc_lps = 0;
    LatencyStats::Summary lat;
    {
      RangexServer server(pl, so);
      auto ch = rangex_channel(server.address());
      const auto t1 = std::chrono::steady_clock::now();
      std::vector<std::thread> feeders;
      std::atomic<int64_t> refused{0};
      for (int lane = 0; lane < nl; ++lane)
        feeders.emplace_back([&, lane] {
          MemorySource src(scans, lane);
          FeedOptions fo;
          fo.window = 128;
          const FeedReport r = Feeder(ch, fo).run(src);
          refused += int64_t(r.refused_total());
        });
      for (auto& f : feeders) f.join();
      server.shutdown();  // waits until every accepted line is decided
      grpc_lps = double(nl) * lines /
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
      lat = server.engine().stats().decision;
      if (refused.load()) std::printf("(%lld lines refused)\n", (long long)refused.load());
    }
    std::filesystem::remove_all(dir);
    std::printf("%-6d %16.0f %16.0f %8.2f   p50 %7.1f ms  p99 %7.1f ms\n", nl, inproc, grpc_lps,
                grpc_lps / inproc, lat.p50, lat.p99);
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace rangex::cli
