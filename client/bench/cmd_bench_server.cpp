// bench-server: lines/s end to end through gRPC on loopback for 1, 4 and 16 lanes, and the
// latency from a fillet's last line to its decision, each beside the in-process pipeline
// (LaneProcessor, no gRPC, no store) on the same lines in the same run.
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>

#include "args.h"
#include "backend_args.h"
#include "bench/bench_commands.h"
#include "bench/bench_gate.h"
#include "bench/memory_source.h"
#include "bench/resident_memory.h"
#include "commands.h"
#include "core/error.h"
#include "feeder.h"
#include "offline/line_path.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/server.h"
#include "sim/plant_simulator.h"

namespace rangex::cli {

namespace pb = rangex::v1;

namespace {
// The server's side of the path, from its statistics: where a line's and a fillet's time
// went, and the bytes copied on the way in.
void print_server_path(const EngineStats& st, int batch_lines) {
  std::printf("   server path, per stage (p50 / p99 of the last 4096, mean of all):\n");
  auto row = [](const std::string& name, const LatencyStats::Summary& l, const char* per) {
    std::printf("     %-26s p50 %8.2f ms  p99 %8.2f ms  mean %8.2f ms  (%llu %s)\n", name.c_str(),
                l.p50, l.p99, l.samples ? l.sum_ms / double(l.samples) : 0.0,
                (unsigned long long)l.samples, per);
  };
  row("queue wait", st.queue_wait, "lines");
  row("line stages (a batch)", st.pipeline, "batches");
  row("inspection wait", st.inspection_wait, "fillets");
  row("inspection", st.inspection, "fillets");
  for (const auto& [name, l] : st.inspection_stages) row("  " + name, l, "fillets");
  row("store (record, images)", st.store, "fillets");
  row("last line -> decision", st.decision, "fillets");
  if (st.pipeline.samples && st.processed)
    std::printf("     line stages per line: %.1f us (batches of up to %d lines)\n",
                1e3 * st.pipeline.sum_ms / double(st.processed), batch_lines);
  if (st.processed)
    std::printf(
        "     bytes copied per line: %.0f kB parsed out of the wire into the request, %.0f kB "
        "into the backend's staging, %.1f kB of X-ray into the assembly\n",
        double(st.bytes_parsed) / double(st.received) / 1e3,
        double(st.batches.bytes_staged) / double(st.processed) / 1e3,
        double(st.bytes_xray_copied) / double(st.processed) / 1e3);
}

// How many streams and subscribers one server holds: every lane fed by two streams at once
// with the same lines (a camera that reconnected while its old stream is still open: one of
// each pair of lines is a duplicate), two subscribers per lane reading every decision.
void capacity(const PlantConfig& plant, const std::vector<pb::LineScan>& scans,
              const BackendRequest& backend) {
  std::printf("\ncapacity: 2 streams per lane sending the same %zu lines, 2 subscribers per lane\n",
              scans.size());
  std::printf("%-6s %8s %12s %10s %12s %14s %14s\n", "lanes", "streams", "subscribers", "lines/s",
              "streams ok", "subscribers ok", "peak streams");
  for (int nl : {16, 32, 64, 128}) {
    const std::string dir =
        (std::filesystem::temp_directory_path() /
         ("rangex-capacity-" + std::to_string(getpid()) + "-" + std::to_string(nl)))
            .string();
    std::filesystem::remove_all(dir);
    PlantConfig pl = plant;
    pl.lanes.resize(1);
    for (int i = 1; i < nl; ++i) {
      pl.lanes.push_back(pl.lanes[0]);
      pl.lanes.back().id = i;
    }
    ServerOptions so;
    so.listen = "127.0.0.1:0";
    so.data_dir = dir;
    so.engine.backend = backend;
    so.engine.images = false;
    so.engine.queue_lines = 4096;
    std::atomic<int> streams_ok{0}, subscribers_ok{0}, peak{0};
    double lps = 0;
    {
      RangexServer server(pl, so);
      auto ch = rangex_channel(server.address());
      std::vector<std::unique_ptr<grpc::ClientContext>> sub_ctx;
      std::vector<std::thread> subs;
      std::vector<int64_t> seen(size_t(2 * nl), 0);
      for (int i = 0; i < 2 * nl; ++i) {
        sub_ctx.push_back(std::make_unique<grpc::ClientContext>());
        subs.emplace_back([&, i] {
          auto stub = pb::ResultsService::NewStub(ch);
          auto reader = stub->SubscribeFillets(sub_ctx[size_t(i)].get(), {});
          pb::SubscribeFilletsResponse r;
          while (reader->Read(&r)) seen[size_t(i)] += 1 + int64_t(r.lagged());
          (void)reader->Finish();
        });
      }
      std::atomic<bool> feeding{true};
      std::thread watch([&] {
        while (feeding) {
          peak = std::max(peak.load(), server.ingest_streams());
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
      });
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<std::thread> feeders;
      for (int lane = 0; lane < nl; ++lane)
        for (int k = 0; k < 2; ++k)
          feeders.emplace_back([&, lane] {
            MemorySource src(scans, lane);
            FeedOptions fo;
            fo.keep_until_durable = false;  // the server's memory is what is measured
            fo.window = 8;
            fo.settle_for_s = 0;  // 400 lines cut a fillet: the shutdown decides it
            const FeedReport r = Feeder(ch, fo).run(src);
            const uint64_t dups =
                r.refused.count("DUPLICATE_LINE") ? r.refused.at("DUPLICATE_LINE") : 0;
            const bool ok = r.status.ok() && r.accepted + dups == r.sent;
            streams_ok += ok;
            static std::atomic<int> told{0};
            if (!ok && told++ < 3) {
              std::fprintf(stderr, "lane %d stream: status '%s', sent %llu accepted %llu:", lane,
                           r.status.error_message().c_str(), (unsigned long long)r.sent,
                           (unsigned long long)r.accepted);
              for (const auto& [code, n] : r.refused)
                std::fprintf(stderr, " %s %llu", code.c_str(), (unsigned long long)n);
              std::fprintf(stderr, "\n");
            }
          });
      for (auto& f : feeders) f.join();
      feeding = false;
      watch.join();
      server.shutdown();
      lps = double(nl) * double(scans.size()) /
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      for (auto& t : subs) t.join();
      const int64_t decided = server.store().count_fillets();
      for (int64_t n : seen) subscribers_ok += n == decided;
    }
    std::filesystem::remove_all(dir);
    std::printf("%-6d %8d %12d %10.0f %12d %14d %14d\n", nl, 2 * nl, 2 * nl, lps, streams_ok.load(),
                subscribers_ok.load(), peak.load());
    std::fflush(stdout);
  }
}

// In-process: the same lines through the server's line path on the CPU backend into each
// lane's LaneProcessor, batches of 64: what the server adds is measured against this.
double in_process_lps(const PlantConfig& plant, const std::vector<pb::LineScan>& scans, int nl,
                      int threads) {
  const LaneConfig& lc = plant.lanes[0];
  const int lines = int(scans.size());
  const size_t frame = size_t(lc.frame_width) * lc.frame_height;
  std::vector<QueuedLine> block;
  const auto t0 = std::chrono::steady_clock::now();
  for (int lane = 0; lane < nl; ++lane) {
    LinePath path({plant.lanes[lane]}, cpu_request(threads));
    LaneProcessor proc(plant.lanes[lane], {false, false}, [](InspectedFillet&&) {});
    path.attach(plant.lanes[lane].id, &proc);
    for (int k0 = 0; k0 < lines; k0 += 64) {
      const int c = std::min(64, lines - k0);
      shape_block(block, c, plant.lanes[lane].id, frame, lc.xray.pixels);
      for (int k = 0; k < c; ++k) {
        const pb::LineScan& scan = scans[k0 + k];
        IncomingLine& in = block[k].line;
        in.encoder = scan.encoder();
        std::memcpy(in.cam0.data(), scan.cam0().data(), frame);
        std::memcpy(in.cam1.data(), scan.cam1().data(), frame);
        std::memcpy(in.xray.data(), scan.xray().data(), scan.xray().size());
      }
      path.run(block);
    }
    proc.finish();
  }
  return double(nl) * lines /
         std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Resident memory while the lanes were fed: the server's share (over the process as it
// was before the server started) at its peak, and its trend from the first fifth of
// the feed to the last.
void print_resident(const std::vector<std::pair<double, int64_t>>& resident,
                    int64_t resident_before, int nl) {
  if (resident.size() >= 10 && resident_before > 0) {
    int64_t peak = 0;
    double first = 0, last = 0;
    const size_t fifth = resident.size() / 5;
    for (size_t k = 0; k < resident.size(); ++k) {
      peak = std::max(peak, resident[k].second);
      if (k < fifth) first += double(resident[k].second) / double(fifth);
      if (k >= resident.size() - fifth) last += double(resident[k].second) / double(fifth);
    }
    std::printf(
        "       resident: +%.0f MB at the peak (%.1f MB a lane), %+.1f MB from the "
        "feed's first fifth to its last (%.1f s)\n",
        double(peak - resident_before) / 1e6, double(peak - resident_before) / 1e6 / nl,
        (last - first) / 1e6, resident.back().first);
    // A long run: resident memory minute by minute (its slope says whether it is flat).
    if (resident.back().first >= 120) {
      std::printf("       resident by minute (MB over the start):");
      // The slope leaves out the first minute (buffers and the store filling).
      double t_next = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
      for (const auto& [t, bytes] : resident) {
        const double y = double(bytes - resident_before) / 1e6;
        if (t >= 60) sx += t, sy += y, sxx += t * t, sxy += t * y, ++m;
        if (t >= t_next) {
          std::printf(" %.0f", y);
          t_next += 60;
        }
      }
      const double slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
      std::printf("\n       slope after the first minute: %+.2f MB per minute\n", 60 * slope);
    }
  }
}

}  // namespace

int cmd_bench_server(int argc, char** argv) {
  const Args a(argc, argv, 2, {"capacity", "path", "plc"},
               {"lines", "threads", "backend", "device", "rate", "lanes", "seconds"});
  a.expect_positionals(
      0,
      "bench-server [--lines N] [--backend cpu|opencl|vulkan|auto|all] "
      "[--device D] [--lanes 1,4,16] [--rate LINES/S [--seconds S] [--plc]] [--path] "
      "[--capacity]");
  // By default one whole scene per lane: a scene cut short leaves its last fillet open, and
  // that fillet ends only when the server stops.
  const long n = a.integer("lines", 0);
  if (a.has("lines") && n < 1) fail("--lines must be >= 1 (got ", n, ")");
  // A fixed rate per lane (a belt's speed) measures latency at a plant's load; without it
  // the feeders send as fast as the server takes lines (throughput).
  const double rate = std::stod(a.get("rate", "0"));
  if (!(rate >= 0)) fail("--rate must be >= 0 lines/s per lane");
  // A long run at a fixed rate (resident memory over time): the scene repeats.
  const double seconds = std::stod(a.get("seconds", "0"));
  if (!(seconds >= 0)) fail("--seconds must be >= 0");
  if (seconds > 0 && rate <= 0) fail("--seconds needs --rate (the run's length is rate x time)");
  // Releases to a simulated PLC whose belts run at the rate: a release is in time or not.
  const bool plc = a.flag("plc");
  if (plc && rate <= 0) fail("--plc needs --rate (the belts' speed)");
  const std::vector<int> lane_counts = a.int_list("lanes", {1, 4, 16}, 16);
  const int threads =
      int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
  std::vector<BackendRequest> backends;
  for (const std::string& name : backend_names(a.get("backend", "cpu"))) {
    BackendRequest r;
    r.name = name;
    r.device = a.get("device", "");
    r.threads = threads;
    backends.push_back(r);
  }
  PlantConfig plant = default_plant_config(16);
  const LaneConfig& lc = plant.lanes[0];
  // One lane's worth of lines with fillets in them, reused on every lane; a repeated scene
  // is whole, so that no fillet is cut where it starts again.
  constexpr int kFillets = 3;
  std::vector<pb::LineScan> scans = render_lane_lines(lc, kFillets, INT64_MAX);
  const int scene_lines = int(scans.size());
  if (seconds <= 0 && n > 0 && n < scene_lines) scans.resize(size_t(n));
  const int lines = int(scans.size());
  const int64_t repeats =
      seconds > 0 ? std::max<int64_t>(1, int64_t(std::ceil(seconds * rate / lines))) : 1;
  const std::string fillets = lines < scene_lines
                                  ? "of a " + std::to_string(kFillets) + "-fillet scene's " +
                                        std::to_string(scene_lines) +
                                        ": its last fillet is cut and ends at the stop"
                                  : std::to_string(kFillets * repeats) + " fillets each";
  std::printf("end to end through gRPC on loopback, %d lines per lane (%s), %d threads, %s\n",
              int(lines * repeats), fillets.c_str(), threads,
              rate > 0 ? ("fed at " + std::to_string(int(rate)) + " lines/s per lane").c_str()
                       : "fed as fast as the server takes lines");
  std::printf("%-6s %-8s %16s %16s %8s %24s\n", "lanes", "backend", "in-process l/s", "gRPC l/s",
              "ratio", "last line -> decision");
  for (int nl : lane_counts) {
    const double inproc = in_process_lps(plant, scans, nl, threads);

    // Through the server on each backend: one stream per lane, all at once.
    for (const BackendRequest& backend : backends) {
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
      so.engine.backend = backend;
      so.engine.queue_lines = 4096;
      double grpc_lps = 0;
      LatencyStats::Summary lat;
      std::string running;
      std::vector<std::pair<double, int64_t>> resident;
      const int64_t resident_before = resident_bytes();
      std::unique_ptr<BenchGate> gate;
      if (plc) gate = std::make_unique<BenchGate>(pl, rate);
      uint64_t clean_late = 0;
      {
        RangexServer server(pl, so);
        auto ch = rangex_channel(server.address());
        ResidentSampler sampler;
        const auto t1 = std::chrono::steady_clock::now();
        std::vector<std::thread> feeders;
        std::atomic<int64_t> refused{0};
        for (int lane = 0; lane < nl; ++lane)
          feeders.emplace_back([&, lane] {
            // At a belt's rate, lanes start a fraction of the scene apart, as a plant's lanes
            // do: fillets of different lanes do not all close at the same moment.
            if (rate > 0)
              std::this_thread::sleep_for(
                  std::chrono::duration<double>(double(lane) / nl * lines / rate));
            MemorySource src(scans, lane, repeats);
            if (gate) gate->start_lane(lane, scans.front().encoder());
            FeedOptions fo;
            fo.keep_until_durable = false;  // the server's memory is what is measured
            fo.window = 128;
            fo.rate = rate;
            // The server's shutdown below decides every line it took. A wait for each lane to
            // be settled would instead wait out the idle close of a fillet the lines cut.
            fo.settle_for_s = 0;
            const FeedReport r = Feeder(ch, fo).run(src);
            refused += int64_t(r.refused_total());
            for (const auto& [code, n] : r.refused)
              std::fprintf(stderr, "lane %d: %llu %s\n", lane, (unsigned long long)n, code.c_str());
          });
        for (auto& f : feeders) f.join();
        resident = sampler.stop();
        server.shutdown();  // waits until every accepted line is decided
        grpc_lps = double(nl) * double(lines * repeats) /
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
        const EngineStats st = server.engine().stats();
        lat = st.decision;
        if (a.flag("path"))
          print_server_path(st, so.engine.batch_lines);
        else if (rate > 0)
          for (const auto& [name, l] : std::vector<std::pair<std::string, LatencyStats::Summary>>{
                   {"queue wait", st.queue_wait},
                   {"line batch", st.pipeline},
                   {"inspection wait", st.inspection_wait},
                   {"inspection", st.inspection}})
            std::printf("   %-16s p50 %7.1f ms  p99 %7.1f ms\n", name.c_str(), l.p50, l.p99);
        running = st.backend.name;
        if (gate) clean_late = gate->report(server.plc(), server.store().count_fillets());
        if (refused.load()) std::printf("(%lld lines refused)\n", (long long)refused.load());
      }
      gate.reset();
      std::filesystem::remove_all(dir);
      std::printf("%-6d %-8s %16.0f %16.0f %8.2f   p50 %7.1f ms  p99 %7.1f ms\n", nl,
                  running.c_str(), inproc, grpc_lps, grpc_lps / inproc, lat.p50, lat.p99);
      if (plc)
        std::printf("       clean fillets diverted for lateness: %llu\n",
                    (unsigned long long)clean_late);
      print_resident(resident, resident_before, nl);
      std::fflush(stdout);
    }
  }
  if (a.flag("capacity"))
    capacity(plant,
             std::vector<pb::LineScan>(scans.begin(),
                                       scans.begin() + std::min<size_t>(scans.size(), 400)),
             backends.front());
  return 0;
}

}  // namespace rangex::cli
