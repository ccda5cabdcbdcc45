// soak: rangexd (in this process, on loopback) fed a simulated plant at a fixed rate for N
// minutes, with a results subscriber and control-plane queries every few seconds, as a
// plant runs it. Reports minute by minute: lines sent and decided, fail-safe rejects, the
// last-line-to-decision p50/p99 of that minute (from the server's histogram), resident
// memory; at the end: lines lost (goal 0), the subscriber's view, resident memory's slope.
// A benchmark, not a test.
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include "args.h"
#include "backend_args.h"
#include "bench/bench_commands.h"
#include "bench/memory_source.h"
#include "bench/resident_memory.h"
#include "commands.h"
#include "core/error.h"
#include "feeder.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/server.h"

namespace rangex::cli {

namespace pb = rangex::v1;

namespace {
// The q-quantile of the samples between two cumulative snapshots of a histogram, linear
// within the bucket it falls in (as Prometheus' histogram_quantile); -1 when none.
double window_quantile(const LatencyStats::Summary& a, const LatencyStats::Summary& b, double q) {
  const uint64_t total = b.samples - a.samples;
  if (total == 0) return -1;
  const double want = q * double(total);
  uint64_t below = 0;
  double lower = 0;
  for (size_t k = 0; k < LatencyStats::kBoundsMs.size(); ++k) {
    const uint64_t cum = b.cumulative[k] - a.cumulative[k];
    if (double(cum) >= want) {
      const double in = double(cum - below);
      return lower + (LatencyStats::kBoundsMs[k] - lower) * (in > 0 ? (want - below) / in : 1.0);
    }
    below = cum;
    lower = LatencyStats::kBoundsMs[k];
  }
  return LatencyStats::kBoundsMs.back();  // beyond the last bound: at least this
}

// Every decision as a subscriber sees it: counted by decision, each lane's in order.
struct SubscriberView {
  std::mutex mu;
  std::map<std::string, uint64_t> by_decision;
  std::map<int, int64_t> last_encoder;
  uint64_t out_of_order = 0, lagged = 0, received = 0;
};

struct SoakOptions {
  double minutes = 30, rate = 600;
  int lanes = 4;
  BackendRequest backend;
};

SoakOptions soak_options(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"minutes", "lanes", "rate", "backend", "device", "threads"});
  a.expect_positionals(0,
                       "soak [--minutes N] [--lanes L] [--rate LINES/S per lane] "
                       "[--backend cpu|opencl|vulkan|auto]");
  SoakOptions o;
  o.minutes = std::stod(a.get("minutes", "30"));
  o.lanes = int(a.integer("lanes", 4));
  o.rate = std::stod(a.get("rate", "600"));
  if (!(o.minutes > 0) || o.minutes > 7 * 24 * 60) fail("--minutes must be within 0..10080");
  if (o.lanes < 1 || o.lanes > 64) fail("--lanes must be within 1..64");
  if (!(o.rate > 0) || o.rate > 100000) fail("--rate must be within 0..100000 lines/s per lane");
  o.backend.name = a.get("backend", "cpu");
  o.backend.device = a.get("device", "");
  o.backend.threads =
      int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
  return o;
}

// What a soak measured, for its summary.
struct SoakRun {
  std::vector<FeedReport> reports;
  SubscriberView view;
  std::atomic<uint64_t> queries_ok{0}, queries_failed{0};
  std::vector<std::pair<double, double>> resident_by_minute;  // (minute, MB over the start)
  EngineStats end{};
  double heap_returned_mb = 0;
};

// The subscriber: every decision, counted, each lane's order checked.
void count_decisions(grpc::ClientReaderInterface<pb::SubscribeFilletsResponse>& reader,
                     SubscriberView& view) {
  pb::SubscribeFilletsResponse r;
  while (reader.Read(&r)) {
    std::lock_guard<std::mutex> lock(view.mu);
    ++view.received;
    ++view.by_decision[pb::Decision_Name(r.fillet().decision())];
    view.lagged += r.lagged();
    auto [it, fresh] = view.last_encoder.try_emplace(r.fillet().lane(), INT64_MIN);
    view.out_of_order += r.fillet().first_encoder() <= it->second;
    it->second = r.fillet().first_encoder();
  }
  reader.Finish();
}

// Control-plane queries as dashboards and operators make them, every 5 s while feeding.
void query_while_feeding(const std::shared_ptr<grpc::Channel>& ch, const std::atomic<bool>& feeding,
                         SoakRun& run) {
  auto control = pb::ControlService::NewStub(ch);
  auto res = pb::ResultsService::NewStub(ch);
  while (feeding) {
    for (int k = 0; k < 50 && feeding; ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    auto deadline = [] {
      auto c = std::make_unique<grpc::ClientContext>();
      c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
      return c;
    };
    pb::GetStatisticsResponse st;
    pb::ListLanesResponse ln;
    pb::ListFilletsRequest lr;
    lr.set_lane(-1);
    lr.set_page_size(50);
    lr.set_from_ns(now_ns() - 60'000'000'000);
    pb::ListFilletsResponse lf;
    for (const grpc::Status& s : {control->GetStatistics(deadline().get(), {}, &st),
                                  control->ListLanes(deadline().get(), {}, &ln),
                                  res->ListFillets(deadline().get(), lr, &lf)})
      (s.ok() ? run.queries_ok : run.queries_failed) += 1;
  }
}

// Minute by minute, from the server's own statistics, until the feeders are done.
void print_minutes(RangexServer& server, const std::atomic<int>& feeders_left,
                   int64_t resident_before, SoakRun& run) {
  const auto t0 = std::chrono::steady_clock::now();
  EngineStats prev = server.engine().stats();
  for (int minute = 1;; ++minute) {
    const auto until = t0 + std::chrono::seconds(60 * minute);
    while (feeders_left > 0 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const EngineStats now = server.engine().stats();
    const double mb = double(resident_bytes() - resident_before) / 1e6;
    const double p50 = window_quantile(prev.decision, now.decision, 0.5);
    const double p99 = window_quantile(prev.decision, now.decision, 0.99);
    std::printf("%6d %12llu %10llu %8llu %10llu %10.1f %10.1f %12.0f\n", minute,
                (unsigned long long)(now.processed - prev.processed),
                (unsigned long long)(now.fillets - prev.fillets),
                (unsigned long long)(now.rejects - prev.rejects),
                (unsigned long long)(now.not_inspected - prev.not_inspected), p50, p99, mb);
    std::fflush(stdout);
    run.resident_by_minute.emplace_back(minute, mb);
    prev = now;
    if (feeders_left == 0) break;
  }
}

// rangexd in this process fed by one feeder a lane, with a subscriber and the queries.
void run_soak(const PlantConfig& plant, const ServerOptions& so, const SoakOptions& o,
              const std::vector<pb::LineScan>& scans, int64_t repeats, SoakRun& run) {
  const int64_t resident_before = resident_bytes();
  RangexServer server(plant, so);
  auto ch = rangex_channel(server.address());
  std::atomic<bool> feeding{true};
  grpc::ClientContext sub_ctx;
  auto results = pb::ResultsService::NewStub(ch);
  auto reader = results->SubscribeFillets(&sub_ctx, {});
  std::thread subscriber([&] { count_decisions(*reader, run.view); });
  std::thread queries([&] { query_while_feeding(ch, feeding, run); });
  ResidentSampler sampler(1000);
  std::vector<std::thread> feeders;
  for (int lane = 0; lane < o.lanes; ++lane)
    feeders.emplace_back([&, lane] {
      std::this_thread::sleep_for(
          std::chrono::duration<double>(double(lane) / o.lanes * double(scans.size()) / o.rate));
      MemorySource src(scans, lane, repeats);
      FeedOptions fo;
      fo.keep_until_durable = false;  // the server's memory is what is measured
      fo.window = 128;
      fo.rate = o.rate;
      run.reports[size_t(lane)] = Feeder(ch, fo).run(src);
    });
  std::atomic<int> feeders_left{o.lanes};
  std::thread watcher([&] {
    for (auto& f : feeders) f.join();
    feeders_left = 0;
  });
  print_minutes(server, feeders_left, resident_before, run);
  watcher.join();
  feeding = false;
  queries.join();
  sampler.stop();
  server.shutdown();  // decides every accepted line; the subscriber's stream then ends
  subscriber.join();
  run.end = server.engine().stats();
  run.heap_returned_mb = double(server.heap_returned()) / 1e6;
}

// The run's totals; 0 when no line was lost.
int print_soak_summary(SoakRun& run, int lanes) {
  const EngineStats& end = run.end;
  uint64_t sent = 0, acked = 0, refused = 0;
  for (const FeedReport& r : run.reports) {
    sent += r.sent;
    acked += r.accepted;
    refused += r.refused_total();
  }
  uint64_t dropped = 0;
  for (const auto& [why, n] : end.dropped) dropped += n;
  // Lost: sent and never acknowledged either way, or accepted and never processed.
  const int64_t lost_in_flight = int64_t(sent) - int64_t(acked) - int64_t(refused);
  const int64_t lost_in_server = int64_t(end.accepted) - int64_t(end.processed);
  std::printf(
      "lines: %llu sent, %llu accepted, %llu refused, %llu processed, %llu dropped; "
      "lost: %lld unacknowledged, %lld accepted and not processed\n",
      (unsigned long long)sent, (unsigned long long)end.accepted, (unsigned long long)refused,
      (unsigned long long)end.processed, (unsigned long long)dropped, (long long)lost_in_flight,
      (long long)lost_in_server);
  std::printf(
      "fillets: %llu decided, %llu rejected, %llu fail-safe (not inspected); last line "
      "to decision over the run p50 %.1f ms, p99 %.1f ms\n",
      (unsigned long long)end.fillets, (unsigned long long)end.rejects,
      (unsigned long long)end.not_inspected,
      window_quantile(LatencyStats::Summary{}, end.decision, 0.5),
      window_quantile(LatencyStats::Summary{}, end.decision, 0.99));
  {
    SubscriberView& view = run.view;
    std::lock_guard<std::mutex> lock(view.mu);
    std::printf(
        "subscriber: %llu decisions (%s), %llu lagged, %llu out of each lane's order; "
        "queries: %llu answered, %llu failed\n",
        (unsigned long long)view.received,
        view.received == end.fillets ? "every one" : "NOT every one",
        (unsigned long long)view.lagged, (unsigned long long)view.out_of_order,
        (unsigned long long)run.queries_ok.load(), (unsigned long long)run.queries_failed.load());
  }
  // Resident memory's slope after the first minute (start-up: buffers and the store).
  const auto& by_minute = run.resident_by_minute;
  double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
  for (const auto& [x, y] : by_minute)
    if (x >= 2) sx += x, sy += y, sxx += x * x, sxy += x * y, ++m;
  if (m >= 2)
    std::printf(
        "resident memory: %+.2f MB per minute after the first (%.0f MB at minute 1, %.0f "
        "at the end; %.1f MB a lane)\n",
        (m * sxy - sx * sy) / (m * sxx - sx * sx), by_minute.front().second,
        by_minute.back().second, by_minute.back().second / lanes);
  std::printf("heap trims gave back %.1f MB over the run\n", run.heap_returned_mb);
  return lost_in_flight == 0 && lost_in_server == 0 ? 0 : 1;
}
}  // namespace

int cmd_soak(int argc, char** argv) {
  const SoakOptions o = soak_options(argc, argv);
  const PlantConfig plant = default_plant_config(o.lanes);
  // Six fillets, some with bone: rejects (with their images) are part of the load.
  const std::vector<pb::LineScan> scans = render_lane_lines(plant.lanes[0], 6, INT64_MAX, 2);
  const int64_t per_lane = int64_t(std::ceil(o.minutes * 60 * o.rate));
  const int64_t repeats = (per_lane + int64_t(scans.size()) - 1) / int64_t(scans.size());
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("rangex-soak-" + std::to_string(getpid())))
          .string();
  std::filesystem::remove_all(dir);
  ServerOptions so;
  so.listen = "127.0.0.1:0";
  so.data_dir = dir;
  so.engine.backend = o.backend;
  std::printf(
      "soak: %d lanes at %.0f lines/s each for %.1f min (%lld lines a lane), a "
      "subscriber, queries every 5 s; store %s\n",
      o.lanes, o.rate, o.minutes, (long long)(repeats * int64_t(scans.size())), dir.c_str());
  std::printf("%6s %12s %10s %8s %10s %10s %10s %12s\n", "minute", "lines", "decided", "rejects",
              "fail-safe", "p50 ms", "p99 ms", "resident MB");
  std::fflush(stdout);
  SoakRun run;
  run.reports.resize(size_t(o.lanes));
  run_soak(plant, so, o, scans, repeats, run);
  std::filesystem::remove_all(dir);
  return print_soak_summary(run, o.lanes);
}

}  // namespace rangex::cli
