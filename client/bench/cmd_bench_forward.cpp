// bench-forward: forwarding to the plant-wide PostgreSQL (plantdb/forwarder.h), beside the
// local store's own write rate measured in the same run: how fast a backlog drains, and the
// lag while a plant's lanes decide fillets at their rate.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>
#include <vector>

#include "args.h"
#include "bench/bench_commands.h"
#include "core/error.h"
#include "plantdb/forwarder.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"
#include "store/store.h"

namespace fs = std::filesystem;

namespace rangex::cli {

namespace {
double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// A decision as the engine stores it: a third rejected with a fragment and an image.
void store_one(Store& s, int lane, int64_t n) {
  StoredFillet f;
  f.lane = lane;
  f.lane_fillet = n;
  f.first_encoder = 1000 + 550 * n;
  f.rows = 420;
  f.decision = n % 3 == 0 ? "reject" : "pass";
  f.reason = n % 3 == 0 ? "1 bone fragment" : "";
  f.calibration_id = "lane-cal-7";
  f.beta0 = 8.1 + 1e-3 * double(n % 17), f.beta1 = -0.031, f.beta2 = 2e-5;
  f.resid_mean_dn = 0.2, f.resid_std_dn = 18.6, f.belt_y0_mm = 0.4 * double(f.first_encoder);
  f.decided_ns = now_ns();
  if (n % 3 == 0)
    f.fragments.push_back({"bone", 12.5, 80.2, 3.1, 7.4, 0.21, 2.2, 40, 47, 100, 106, 0});
  const int64_t uid = s.add_fillet(f);
  if (n % 3 == 0) s.add_image(uid, "overlay", s.image_dir(uid) + "/overlay.png");
  if (n % 50 == 0) s.audit("bench", "note", "fillet " + std::to_string(uid));
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[size_t(q * double(v.size() - 1))];
}
}  // namespace

int cmd_bench_forward(int argc, char** argv) {
  const Args a(argc, argv, 2, {},
               {"db", "fillets", "lanes", "rate", "seconds", "lines-per-fillet"});
  a.expect_positionals(0,
                       "bench-forward --db CONNSTR [--fillets 5000] [--lanes 8] [--rate 1250] "
                       "[--seconds 30] [--lines-per-fillet 550]");
  if (!a.has("db")) fail("bench-forward needs --db CONNSTR (a database it may write to)");
  const std::string conninfo = no_password(a.get("db", ""), "--db");
  const int fillets = int(a.integer("fillets", 5000));
  const int lanes = int(a.integer("lanes", 8));
  const double rate = std::stod(a.get("rate", "1250"));
  const double seconds = std::stod(a.get("seconds", "30"));
  const double lines_per_fillet = std::stod(a.get("lines-per-fillet", "550"));
  if (fillets < 1 || lanes < 1 || !(rate > 0) || !(seconds > 0) || !(lines_per_fillet > 0))
    fail("bench-forward: --fillets, --lanes, --rate, --seconds and --lines-per-fillet must be > 0");
  {
    PgConnection db(conninfo);
    plant_db_migrate(db);
  }
  const fs::path root =
      fs::temp_directory_path() / ("rangex-bench-forward-" + std::to_string(getpid()));
  const std::string run =
      "bench-" + std::to_string(getpid()) + "-" + std::to_string(now_ns() / 1000000);
  std::printf(
      "bench-forward: PostgreSQL at %s; every third fillet rejected with an image, an "
      "audit entry every 50\n",
      pg_where(conninfo).c_str());

  // 1. The baseline: the local store's own durable write rate (one fsync per decision).
  Store backlog((root / "backlog").string());
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < fillets; ++i) store_one(backlog, i % lanes, i / lanes);
  const double store_s = seconds_since(t0);
  const int64_t links = backlog.head_seq();
  std::printf("  store (baseline):   %d fillets, %lld chain links in %.2f s: %.0f fillets/s\n",
              fillets, (long long)links, store_s, fillets / store_s);

  // 2. A backlog drained (a server back after an outage).
  {
    ForwarderOptions o;
    o.conninfo = conninfo, o.server_id = run + "-backlog", o.host = "bench", o.idle_s = 0.01;
    Forwarder f(backlog, o);
    t0 = std::chrono::steady_clock::now();
    f.start();
    if (!f.wait_caught_up(600))
      fail("bench-forward: the backlog did not drain: ", f.status().last_error);
    const double s = seconds_since(t0);
    std::printf(
        "  forward (backlog):  %lld links, %lld images in %.2f s: %.0f fillets/s, %.0f "
        "links/s, %.2fx the store's rate\n",
        (long long)f.status().links, (long long)f.status().images, s, fillets / s,
        double(f.status().links) / s, (fillets / s) / (fillets / store_s));
  }

  // 3. A plant's load: lanes deciding fillets at their rate while the forwarder follows.
  Store live((root / "live").string());
  ForwarderOptions o;
  o.conninfo = conninfo, o.server_id = run + "-live", o.host = "bench";
  Forwarder f(live, o);
  f.start();
  const double per_s = lanes * rate / lines_per_fillet;
  std::vector<double> lag_s, lag_n;
  std::thread sampler;
  std::atomic<bool> done{false};
  sampler = std::thread([&] {
    while (!done) {
      // Measured here, from the store and the cursor the database acknowledged, not taken
      // from the forwarder's own figures.
      ForwardCursor c;
      c.seq = f.status().forwarded_seq;
      const ForwardBatch b = live.forward_batch(c, 1, false);
      lag_n.push_back(double(b.pending));
      lag_s.push_back(b.pending > 0 ? double(now_ns() - b.oldest_ns) * 1e-9 : 0.0);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
  t0 = std::chrono::steady_clock::now();
  int64_t n = 0;
  while (seconds_since(t0) < seconds) {
    const double due = seconds_since(t0) * per_s;
    while (double(n) < due) store_one(live, int(n % lanes), n / lanes), ++n;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const bool caught = f.wait_caught_up(60);
  done = true;
  sampler.join();
  std::printf(
      "  plant load:         %d lanes x %.0f lines/s (%.1f fillets/s at %.0f lines a "
      "fillet) for %.0f s: %lld fillets\n",
      lanes, rate, per_s, lines_per_fillet, seconds, (long long)n);
  std::printf(
      "                      lag p50 %.2f s / %.0f records, p99 %.2f s / %.0f records, "
      "max %.2f s / %.0f records; %s\n",
      quantile(lag_s, 0.5), quantile(lag_n, 0.5), quantile(lag_s, 0.99), quantile(lag_n, 0.99),
      quantile(lag_s, 1.0), quantile(lag_n, 1.0),
      caught ? "caught up at the end" : "NOT caught up 60 s after the end");
  f.stop();
  std::error_code ec;
  fs::remove_all(root, ec);
  return caught ? 0 : 1;
}

}  // namespace rangex::cli
