// rangexd: the inspection server. Loads the plant configuration, opens its store, serves
// rangex.v1 over gRPC (loopback by default) until SIGINT/SIGTERM/SIGHUP, then drains and stops.
// Exits non-zero when it cannot inspect for `server.exit_after_s` (a stalled worker, a failed
// store) or cannot drain within `server.drain_timeout_s`, so that a supervisor (systemd,
// Kubernetes) restarts it; results and calibrations survive in the store.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "core/error.h"
#include "core/open_file_limit.h"
#include "fleet/fleet_server.h"
#include "plantdb/forwarder.h"
#include "plantdb/pg_connection.h"
#include "service/http_server.h"
#include "service/server.h"

namespace {
volatile std::sig_atomic_t g_stop = 0;  // the signal that asked for the stop
void on_signal(int sig) {
  g_stop = sig;
}

// SIGINT, SIGTERM and SIGHUP stop rangexd the same way: it decides what it accepted and hands
// the rest back. SIGHUP's default had ended it at once, undrained (exit 129): a terminal
// closing on a hand-started rangexd, or a reload sent to a service that has none to do.
// SIGPIPE is ignored: a reader of its output that went away fails that write, not the line.
void stop_on_signals() {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, on_signal);
  std::signal(SIGPIPE, SIG_IGN);
}

constexpr const char* kUsage =
    "usage: rangexd [--config PLANT.yaml] [--listen HOST:PORT] [--http HOST:PORT|off]\n"
    "               [--data DIR] [--threads N]\n"
    "               [--queue LINES] [--batch LINES] [--backend auto|cpu|opencl|vulkan]\n"
    "               [--device INDEX|NAME] [--server-id ID]\n"
    "       rangexd --fleet [--config PLANT.yaml] [--http HOST:PORT] [--servers-ca FILE]\n"
    "  --backend and --device override plant.backend and plant.device; --threads is the\n"
    "  CPU backend's stripe workers. --server-id overrides plant.server_id (default: the host\n"
    "  name): where lanes name their server, this server runs the lanes named for it.\n"
    "  --fleet serves the dashboard over plant.results_db for every server forwarding there\n"
    "  (read-only; --http defaults to 127.0.0.1:8090); --servers-ca verifies the servers'\n"
    "  https dashboards when images are fetched from them.\n";

void print_stats(rangex::RangexServer& server) {
  const auto s = server.engine().stats();
  std::fprintf(stderr, "rangexd: %llu lines received, %llu accepted, %llu processed, %d queued\n",
               (unsigned long long)s.received, (unsigned long long)s.accepted,
               (unsigned long long)s.processed, s.queue_depth);
}
// The fleet view: every server's records from the plant-wide database, until SIGINT/SIGTERM/SIGHUP.
int run_fleet(const rangex::PlantConfig& plant, const std::string& http,
              const std::string& servers_ca) {
  rangex::FleetOptions fo;
  fo.conninfo = plant.results_db;
  if (!http.empty()) fo.listen = http;
  fo.plant = plant.name;
  fo.security = plant.security;
  fo.servers_ca = servers_ca;
  rangex::FleetServer fleet(fo);
  stop_on_signals();
  std::printf("rangexd: fleet view of plant '%s' over PostgreSQL at %s, at %s://%s/\n",
              plant.name.c_str(), rangex::pg_where(plant.results_db).c_str(),
              fleet.tls() ? "https" : "http", fleet.address().c_str());
  std::fflush(stdout);
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  fleet.stop();
  std::printf("rangexd: fleet view stopped\n");
  return 0;
}
// What the command line asks for; empty strings and zeros leave the plant file's values.
struct Args {
  std::string config, listen, http, data, backend, device, servers_ca, server_id;
  bool fleet = false;
  int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  long queue = 0, batch = 0;
};

// Exits 2 with the usage on a bad option, 0 after --help.
Args parse_args(int argc, char** argv) {
  Args o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "rangexd: %s needs a value\n%s", a.c_str(), kUsage);
        std::exit(2);
      }
      return argv[++i];
    };
    auto number = [&](const std::string& v) {
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end || n <= 0) {
        std::fprintf(stderr, "rangexd: %s needs a positive integer (got '%s')\n", a.c_str(),
                     v.c_str());
        std::exit(2);
      }
      return n;
    };
    if (a == "--config")
      o.config = value();
    else if (a == "--listen")
      o.listen = value();
    else if (a == "--http")
      o.http = value();
    else if (a == "--data")
      o.data = value();
    else if (a == "--threads")
      o.threads = int(number(value()));
    else if (a == "--backend")
      o.backend = value();
    else if (a == "--device")
      o.device = value();
    else if (a == "--queue")
      o.queue = number(value());
    else if (a == "--batch")
      o.batch = number(value());
    else if (a == "--fleet")
      o.fleet = true;
    else if (a == "--servers-ca")
      o.servers_ca = value();
    else if (a == "--server-id")
      o.server_id = value();
    else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else {
      std::fprintf(stderr, "rangexd: unknown option %s\n%s", a.c_str(), kUsage);
      std::exit(2);
    }
  }
  if (!o.backend.empty() && o.backend != "auto" && o.backend != "cpu" && o.backend != "opencl" &&
      o.backend != "vulkan") {
    std::fprintf(stderr, "rangexd: --backend must be auto, cpu, opencl or vulkan (got '%s')\n",
                 o.backend.c_str());
    std::exit(2);
  }
  if (o.config.empty()) {
    if (const char* env = std::getenv("RANGEX_CONFIG"))
      o.config = env;
    else
      o.config = std::filesystem::exists("config/plant.yaml") ? "config/plant.yaml"
                                                              : RANGEX_DEFAULT_CONFIG;
  }
  return o;
}

rangex::ServerOptions server_options(const rangex::PlantConfig& plant, const Args& a) {
  rangex::ServerOptions opt;
  opt.listen = a.listen;
  opt.data_dir = a.data;
  static_cast<rangex::EngineSettings&>(opt.engine) = plant.engine;
  opt.engine.backend.name = a.backend.empty() ? plant.backend : a.backend;
  opt.engine.backend.device = a.device.empty() ? plant.device : a.device;
  opt.engine.backend.threads = a.threads;
  if (a.queue) opt.engine.queue_lines = size_t(a.queue);
  if (a.batch) opt.engine.batch_lines = int(a.batch);
  opt.on_fatal = [](const rangex::Health& h) {
    for (const std::string& r : h.reasons)
      std::fprintf(stderr, "rangexd: cannot inspect: %s\n", r.c_str());
    // Nothing accepted is lost by exiting: no durable count has passed a decision the
    // store did not take, so the feeders still hold those lines and resend them.
    std::fprintf(stderr,
                 "rangexd: not serving for longer than exit_after_s; exiting (the lines not "
                 "yet durable are handed back: feeders resend them to the next server)\n");
    std::fflush(stderr);
    std::_Exit(3);  // nothing can be drained through a stalled worker
  };
  return opt;
}

// The dashboard and /metrics, over the same engine, store and results hub; none for "off".
std::unique_ptr<rangex::HttpServer> start_dashboard(rangex::RangexServer& server,
                                                    const rangex::PlantConfig& plant,
                                                    const std::string& http) {
  const std::string where = http.empty() ? plant.http : http;
  if (where == "off") return nullptr;
  rangex::HttpOptions ho;
  ho.listen = where;
  ho.security = plant.security;
  ho.ingest_streams = [&server] { return server.ingest_streams(); };
  return std::make_unique<rangex::HttpServer>(server.engine(), server.store(), server.hub(), ho);
}

// What a plant engineer reads first in the log: where it listens, its lanes, its security,
// constants not fitted to this plant, the backend and the dashboard.
void print_banner(rangex::RangexServer& server, const rangex::PlantConfig& plant,
                  const std::string& store, const rangex::HttpServer* web) {
  const rangex::BackendInfo b = server.engine().backend();
  std::printf("rangexd: plant '%s', %zu lanes, listening on %s, store %s\n", plant.name.c_str(),
              plant.lanes.size(), server.address().c_str(), store.c_str());
  if (!plant.lane_servers.empty()) {
    std::string ids;
    for (const rangex::LaneConfig& l : plant.lanes)
      ids += (ids.empty() ? "" : ", ") + std::to_string(l.id);
    std::printf("rangexd: server %s runs lanes %s of the plant file\n", plant.server_id.c_str(),
                ids.c_str());
  }
  const rangex::SecurityConfig& sec = plant.security;
  std::printf("rangexd: %s; %s%s; clients without credentials: %s\n",
              sec.tls() ? "TLS" : "plaintext", sec.client_ca.empty() ? "" : "client certificates, ",
              sec.tokens.empty() ? "no tokens" : "bearer tokens",
              rangex::role_name(sec.anonymous_role()));
  for (const rangex::LaneConfig& l : plant.lanes)
    if (const std::string w = rangex::unfitted_constants(l); !w.empty())
      std::fprintf(stderr, "rangexd: warning: %s\n", w.c_str());
  std::printf("rangexd: backend %s (%s): %s, %s; %s\n", b.name.c_str(),
              server.engine().backend_note().c_str(), b.device.c_str(), b.driver.c_str(),
              b.limits.c_str());
  if (web)
    std::printf("rangexd: dashboard at %s://%s/ (metrics at /metrics)\n",
                web->tls() ? "https" : "http", web->address().c_str());
  std::fflush(stdout);
}

// Serves until SIGINT/SIGTERM/SIGHUP, then decides the queued lines and stops.
int serve(const rangex::PlantConfig& plant, const Args& a) {
  const rangex::ServerOptions opt = server_options(plant, a);
  rangex::RangexServer server(plant, opt);
  std::unique_ptr<rangex::HttpServer> web = start_dashboard(server, plant, a.http);
  // The fleet view (a plant-wide database) reads where this dashboard serves and the
  // server's health; nothing reads the dashboard after this scope.
  rangex::PlantHistory no_history;
  if (web)
    server.describe_for_fleet(web->url(), [&web] { return web->health_text(); });
  else
    server.describe_for_fleet("", [&server, &no_history] {
      return rangex::server_health_text(server.engine(), no_history, rangex::HttpOptions{}.version);
    });
  struct Undescribe {
    rangex::RangexServer& s;
    ~Undescribe() { s.describe_for_fleet("", nullptr); }
  } undescribe{server};
  stop_on_signals();
  print_banner(server, plant, a.data.empty() ? plant.storage : a.data, web.get());
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::printf(
      "rangexd: stopping (SIG%s): deciding the queued lines; new lines and the fillets still "
      "coming in are handed back to the feeders\n",
      sigabbrev_np(g_stop));
  std::fflush(stdout);
  if (!server.shutdown(rangex::OpenFillets::kHandBack)) {
    print_stats(server);
    std::fprintf(stderr,
                 "rangexd: could not drain within %.0f s; the lines not decided are not "
                 "durable: feeders resend them to the next server\n",
                 opt.engine.drain_timeout_s);
    std::fflush(stderr);
    std::_Exit(3);
  }
  // The dashboard's event streams have every decision and have ended; then it stops.
  if (web) web->stop();
  const auto s = server.engine().stats();
  std::printf("rangexd: stopped after %llu lines, %llu fillets\n", (unsigned long long)s.processed,
              (unsigned long long)s.fillets);
  return 0;
}

// Each client's connection holds an open file: the soft limit up to the hard one, said at
// start, and a warning where the hard one leaves a plant's clients room to exhaust them.
void raise_open_files() {
  const rangex::OpenFileLimit l = rangex::raise_open_file_limit();
  const auto n = [](uint64_t v) { return (unsigned long long)v; };
  if (!l.error.empty())
    std::fprintf(stderr, "rangexd: warning: the open-file limit stays %llu: %s\n", n(l.now),
                 l.error.c_str());
  else if (l.now > l.before)
    std::printf("rangexd: open files: up to %llu (raised from %llu)\n", n(l.now), n(l.before));
  if (l.now < rangex::kFewOpenFiles)
    std::fprintf(stderr,
                 "rangexd: warning: only %llu open files (hard limit %llu): that many idle "
                 "connections lock every client out; raise the hard limit (systemd: "
                 "LimitNOFILE=65536)\n",
                 n(l.now), n(l.hard));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse_args(argc, argv);
  raise_open_files();
  try {
    rangex::PlantConfig plant = rangex::load_plant_config(a.config);
    if (a.fleet) return run_fleet(plant, a.http, a.servers_ca);
    // One plant file for several servers: this one runs the lanes it names for it.
    if (!a.server_id.empty()) plant.server_id = a.server_id;
    if (plant.server_id.empty() && !plant.lane_servers.empty())
      plant.server_id = rangex::host_name();
    plant = rangex::plant_for_server(plant, plant.server_id);
    return serve(plant, a);
  } catch (const rangex::Error& e) {
    std::fprintf(stderr, "rangexd: error: %s\n", e.what());
    return 1;
  }
}
