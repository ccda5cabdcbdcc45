#include "service/http_server.h"

#include <httplib.h>
#include <linux/sockios.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <sys/ioctl.h>
#include <sys/socket.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "pipeline/product_drift.h"
#include "service/fillet_csv.h"
#include "service/gated_http_server.h"
#include "service/http_params.h"
#include "service/image_view.h"
#include "service/metrics_text.h"
#include "service/pb_convert.h"
#include "web_assets.h"

namespace rangex {

using json = nlohmann::json;

namespace {

int64_t wall_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

json fragment_json(const StoredFragment& g) {
  return {{"kind", g.kind},         {"x_mm", g.x_mm},     {"y_mm", g.y_mm},
          {"area_mm2", g.area_mm2}, {"peak_z", g.peak_z}, {"attenuation_mm2", g.attenuation_mm2},
          {"meat_mm", g.meat_mm},   {"row0", g.row0},     {"row1", g.row1},
          {"col0", g.col0},         {"col1", g.col1}};
}

json fillet_json(const StoredFillet& f) {
  json frags = json::array();
  for (const StoredFragment& g : f.fragments) frags.push_back(fragment_json(g));
  return {{"uid", f.uid},
          {"lane", f.lane},
          {"lane_fillet", f.lane_fillet},
          {"first_encoder", f.first_encoder},
          {"rows", f.rows},
          {"decision", f.decision},
          {"reason", f.reason},
          {"calibration", f.calibration_id},
          {"beta0", f.beta0},
          {"beta1", f.beta1},
          {"beta2", f.beta2},
          {"resid_mean_dn", f.resid_mean_dn},
          {"resid_std_dn", f.resid_std_dn},
          {"belt_y0_mm", f.belt_y0_mm},
          {"decided_ns", f.decided_ns},
          {"fragments", frags}};
}

const LaneCounts* find_lane(const HistorySample& s, int lane) {
  for (const LaneCounts& c : s.lanes)
    if (c.lane == lane) return &c;
  return nullptr;
}

// What an operator's tile shows of a lane, and its light: grey (never fed), red (stopped:
// fed and silent for more than 5 s, or restarted in the last minute), amber (more than 2 %
// of the last 5 minutes' fillets not inspected), green.
json lane_json(const LaneState& l, PlantHistory& h, const std::string& backend) {
  double line_rate = 0, fillets_per_min = 0, reject_rate = 0, ni_rate = 0;
  HistorySample a, b;
  if (h.window(10'000'000'000, a, b)) {
    const LaneCounts *ca = find_lane(a, l.config.id), *cb = find_lane(b, l.config.id);
    const double dt = double(b.t_ns - a.t_ns) / 1e9;
    if (ca && cb && dt > 0) line_rate = double(cb->processed - ca->processed) / dt;
  }
  if (h.window(300'000'000'000, a, b)) {
    const LaneCounts *ca = find_lane(a, l.config.id), *cb = find_lane(b, l.config.id);
    const double dt = double(b.t_ns - a.t_ns) / 1e9;
    if (ca && cb && dt > 0) {
      const double n = double(cb->fillets - ca->fillets);
      fillets_per_min = 60 * n / dt;
      if (n > 0) {
        reject_rate = double(cb->rejects - ca->rejects) / n;
        ni_rate = double(cb->not_inspected - ca->not_inspected) / n;
      }
    }
  }
  std::string light = "green", why = "inspecting";
  if (!l.fed) {
    light = "grey", why = "never fed";
  } else if (l.idle_ms > 5000) {
    light = "red", why = "stopped: no line for " + std::to_string(l.idle_ms / 1000) + " s";
  } else if (ni_rate > 0.02) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.1f %% of the last 5 minutes' fillets not inspected",
                  100 * ni_rate);
    light = "amber", why = buf;
  }
  if (l.product_drift && light == "green")
    light = "amber", why = product_drift_warning(l.config.id, l.drift_fillets, l.implied_frr);
  const LearnedDetection& learned = l.config.inspection.learned;
  return {
      {"lane", l.config.id},
      {"learned_version", learned.active() ? learned.version : ""},
      {"learned_sensitivity", learned.active() ? learned.sensitivity : std::vector<std::string>{}},
      {"false_reject_target", l.config.inspection.false_reject_target},
      {"implied_false_reject_rate", l.implied_frr},
      {"drift_fillets", l.drift_fillets},
      {"product_drift", l.product_drift},
      {"fed", l.fed},
      {"idle_ms", l.idle_ms},
      {"calibration", l.calibration_id},
      {"fillet_in_progress", l.fillet_in_progress},
      {"restarts", l.restarts},
      {"last_restart", l.last_restart},
      {"received", l.received},
      {"processed", l.processed},
      {"fillets", l.fillets},
      {"rejects", l.rejects},
      {"not_inspected", l.not_inspected},
      {"refused", l.refused},
      {"dropped", l.dropped},
      {"line_rate", line_rate},
      {"fillets_per_min", fillets_per_min},
      {"reject_rate", reject_rate},
      {"not_inspected_rate", ni_rate},
      {"light", light},
      {"light_reason", why},
      {"backend", backend}};
}

// The images the store keeps of a fillet (rejects and fillets not inspected have them).
json image_kinds(Store& store, int64_t uid) {
  json kinds = json::array();
  for (const char* k : {"overlay", "xray", "thickness", "pseudo_xray", "residual"})
    if (store.image_path(uid, k)) kinds.push_back(k);
  return kinds;
}

void send_json(httplib::Response& res, const json& j) {
  res.set_content(j.dump(), "application/json");
}

// Event streams beat every half second with a padded comment, so that a client that stops
// reading fills its socket's buffers within seconds (8 kB/s per dashboard) and shows as
// behind: the kernel would otherwise take a quiet line's few bytes for ever.
constexpr auto kBeatPeriod = std::chrono::milliseconds(500);
constexpr size_t kBeatBytes = 4096;
// An event stream's own send buffer: what it may hold unread on our side.
constexpr int kEventSendBuffer = 16 * 1024;

// Bytes sent on a connection and not yet taken by its client.
int unread_bytes(int fd) {
  int queued = 0;
  return fd >= 0 && ::ioctl(fd, SIOCOUTQ, &queued) == 0 ? queued : 0;
}

// The server's certificate and key; with a client CA, client certificates are asked for and
// verified when presented (a browser without one logs in with a token instead).
bool setup_tls(SSL_CTX& ctx, const SecurityConfig& s, std::string& why) {
  auto failed = [&](const std::string& what) {
    char buf[256] = "";
    ERR_error_string_n(ERR_get_error(), buf, sizeof buf);
    why = what + " (" + buf + ")";
    return false;
  };
  SSL_CTX_set_min_proto_version(&ctx, TLS1_2_VERSION);
  // A client may not make the server renegotiate (a handshake's cost, asked for again).
  SSL_CTX_set_options(&ctx, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
  if (SSL_CTX_use_certificate_chain_file(&ctx, s.tls_cert.c_str()) != 1)
    return failed("security.tls.cert: cannot load " + s.tls_cert);
  if (SSL_CTX_use_PrivateKey_file(&ctx, s.tls_key.c_str(), SSL_FILETYPE_PEM) != 1)
    return failed("security.tls.key: cannot load " + s.tls_key);
  if (SSL_CTX_check_private_key(&ctx) != 1)
    return failed("security.tls.key does not match security.tls.cert");
  if (!s.client_ca.empty()) {
    if (SSL_CTX_load_verify_locations(&ctx, s.client_ca.c_str(), nullptr) != 1)
      return failed("security.tls.client_ca: cannot load " + s.client_ca);
    SSL_CTX_set_client_CA_list(&ctx, SSL_load_client_CA_file(s.client_ca.c_str()));
    SSL_CTX_set_verify(&ctx, SSL_VERIFY_PEER, nullptr);
  }
  return true;
}

// The common name of the client's verified certificate ("" without one).
std::string peer_common_name(const httplib::Request& req) {
  if (!req.ssl) return "";
  X509* cert = SSL_get0_peer_certificate(req.ssl);
  if (!cert || SSL_get_verify_result(req.ssl) != X509_V_OK) return "";
  char cn[256] = "";
  if (X509_NAME_get_text_by_NID(X509_get_subject_name(cert), NID_commonName, cn, sizeof cn) <= 0)
    return "";
  return cn;
}

}  // namespace

// One live event stream: a hub subscription whose wake() rings this bell.
struct EventClient {
  std::mutex mu;
  std::condition_variable cv;
  bool rung = false;
  std::shared_ptr<ResultsHub::Subscription> sub;
  int fd = -1;  // the connection
  std::atomic<bool> evicted{false};
};

HttpServer::HttpServer(Engine& engine, Store& store, ResultsHub& hub, HttpOptions opt)
    : engine_(engine), store_(store), hub_(hub), opt_(std::move(opt)), access_(opt_.security) {
  check_listen_security(opt_.listen, opt_.security, "the dashboard");
  const size_t colon = opt_.listen.rfind(':');
  if (colon == std::string::npos)
    fail("plant.http '", opt_.listen, "' must be host:port (port 0: any free one)");
  host_ = opt_.listen.substr(0, colon);
  int want = 0;
  try {
    want = std::stoi(opt_.listen.substr(colon + 1));
  } catch (const std::exception&) {
    fail("plant.http '", opt_.listen, "': the port is not a number");
  }
  if (want < 0 || want > 65535) fail("plant.http '", opt_.listen, "': port out of range");
  // Event streams hold a worker each while open: the gate has room for all of them and for
  // the ordinary requests beside them.
  GateOptions g;
  g.workers = opt_.max_event_streams + 8;
  SSL_CTX* tls = nullptr;
  if (opt_.security.tls()) {
    std::string why;
    tls = SSL_CTX_new(TLS_server_method());
    if (!tls || !setup_tls(*tls, opt_.security, why)) {
      if (tls) SSL_CTX_free(tls);
      fail("plant.http: TLS: ", why.empty() ? "cannot set up" : why);
    }
  }
  auto gated = std::make_unique<GatedHttpServer>(g, tls);
  gate_ = &gated->gate();
  http_ = std::move(gated);
  http_->set_read_timeout(10, 0);
  http_->set_write_timeout(10, 0);
  authorise(*http_);
  routes();
  port_ =
      want == 0 ? http_->bind_to_any_port(host_) : (http_->bind_to_port(host_, want) ? want : -1);
  if (port_ <= 0)
    fail("plant.http: cannot listen on ", opt_.listen, " (in use, or no such address)");
  history_.add(PlantHistory::sample(engine_.stats(), engine_.lanes(), wall_ns()));
  listener_ = std::thread([this] { http_->listen_after_bind(); });
  // Serving before the constructor returns: a stop() that came before the listener started
  // would find nothing to stop, and the listener would then never return.
  for (int k = 0; k < 500 && !http_->is_running(); ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  sampler_ = std::thread([this] { sampler(); });
}

HttpServer::~HttpServer() {
  stop();
}

std::string HttpServer::address() const {
  return host_ + ":" + std::to_string(port_);
}

void HttpServer::stop() {
  if (stopping_.exchange(true)) return;
  http_->stop();
  if (gate_) gate_->stop();
  if (listener_.joinable()) listener_.join();
  if (sampler_.joinable()) sampler_.join();
}

void HttpServer::sampler() {
  const auto period = std::chrono::duration<double>(opt_.history_period_s);
  auto next = std::chrono::steady_clock::now() + period;
  while (!stopping_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (std::chrono::steady_clock::now() < next) continue;
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    history_.add(PlantHistory::sample(engine_.stats(), engine_.lanes(), wall_ns()));
  }
}

bool HttpServer::refuse_hostile(const httplib::Request& req, httplib::Response& res) {
  // cpp-httplib 0.11 bounds each header line (8 kB) but not their number, and serves every
  // part of a multi-range request: 2,600 parts of "bytes=0-" turned a 7.9 kB image into a
  // 248 MB response. No browser or dashboard asks for more than one range.
  if (req.headers.size() > kMaxHeaders) {
    res.status = 431;
    res.set_content(
        json{{"error", "more than " + std::to_string(kMaxHeaders) + " request headers (" +
                           std::to_string(req.headers.size()) + ")"}}
            .dump(),
        "application/json");
    return true;
  }
  if (req.ranges.size() > 1) {
    const size_t parts = req.ranges.size();
    // Cleared, or httplib would still cut the refusal into those parts.
    const_cast<httplib::Request&>(req).ranges.clear();
    res.status = 416;
    res.set_content(json{{"error", "multi-range requests are not served (" + std::to_string(parts) +
                                       " ranges); ask for one range"}}
                        .dump(),
                    "application/json");
    return true;
  }
  return false;
}

void HttpServer::authorise(httplib::Server& s) {
  // Every request, before routing: the dashboard's files too, so that a page never loads
  // without its data.
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (refuse_hostile(req, res)) return httplib::Server::HandlerResponse::Handled;
    try {
      const Identity who = access_.identify(peer_common_name(req),
                                            req.get_header_value("Authorization"), req.remote_addr);
      AccessControl::require(who, Role::viewer, "reading the dashboard");
      return httplib::Server::HandlerResponse::Unhandled;
    } catch (const Unauthenticated& e) {
      res.status = 401;
      res.set_header("WWW-Authenticate", "Basic realm=\"rangex\", charset=\"UTF-8\"");
      res.set_content(json{{"error", e.what()}}.dump(), "application/json");
    } catch (const PermissionDenied& e) {
      res.status = 403;
      res.set_content(json{{"error", e.what()}}.dump(), "application/json");
    }
    return httplib::Server::HandlerResponse::Handled;
  });
}

void HttpServer::routes() {
  httplib::Server& s = *http_;
  s.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
        std::string msg = "internal error";
        int status = 500;
        try {
          std::rethrow_exception(ep);
        } catch (const BadRequest& e) {
          msg = e.what(), status = 400;
        } catch (const NotFound& e) {
          msg = e.what(), status = 404;
        } catch (const std::exception& e) {
          msg = e.what();
        }
        res.status = status;
        res.set_content(json{{"error", msg}}.dump(), "application/json");
      });

  for (const WebAsset& a : kWebAssets) {
    const std::string path = std::string("/") + (std::string(a.path) == "index.html" ? "" : a.path);
    s.Get(path, [a](const httplib::Request&, httplib::Response& res) {
      res.set_content(a.body, a.size, a.type);
      res.set_header("Cache-Control", "no-cache");
    });
  }

  s.Get("/api/info", [this](const httplib::Request&, httplib::Response& res) {
    const BackendInfo b = engine_.backend();
    send_json(res, {{"version", opt_.version},
                    {"plant", engine_.plant().name},
                    {"lanes", engine_.plant().lanes.size()},
                    {"backend", b.name},
                    {"device", b.device},
                    {"backend_note", engine_.backend_note()},
                    {"now_ns", wall_ns()}});
  });
  s.Get("/api/lanes", [this](const httplib::Request&, httplib::Response& res) {
    const std::string backend = engine_.backend().name;
    json out = json::array();
    for (const LaneState& l : engine_.lanes()) out.push_back(lane_json(l, history_, backend));
    send_json(res, out);
  });
  s.Get("/api/statistics", [this](const httplib::Request&, httplib::Response& res) {
    // GetStatistics itself, in protobuf's JSON mapping: the same fields, the same figures.
    v1::GetStatisticsResponse st;
    fill(&st, engine_.stats());
    st.set_subscribers(hub_.subscribers());
    st.set_ingest_streams(opt_.ingest_streams ? opt_.ingest_streams() : 0);
    res.set_content(to_json(st), "application/json");
  });
  s.Get("/api/history", [this](const httplib::Request& req, httplib::Response& res) {
    const int64_t minutes = int_param(req.params, "minutes", 60, 1, 60);
    const std::vector<HistorySample> h = history_.since(wall_ns() - minutes * 60'000'000'000);
    json out = json::array();
    for (size_t k = 1; k < h.size(); ++k) {
      const double dt = double(h[k].t_ns - h[k - 1].t_ns) / 1e9;
      if (dt <= 0) continue;
      out.push_back(
          {{"t_ns", h[k].t_ns},
           {"lines_per_s", double(h[k].processed - h[k - 1].processed) / dt},
           {"fillets_per_min", 60 * double(h[k].fillets - h[k - 1].fillets) / dt},
           {"rejects_per_min", 60 * double(h[k].rejects - h[k - 1].rejects) / dt},
           {"not_inspected_per_min", 60 * double(h[k].not_inspected - h[k - 1].not_inspected) / dt},
           {"decision_p50_ms", h[k].decision_p50_ms},
           {"decision_p99_ms", h[k].decision_p99_ms},
           {"inspection_p50_ms", h[k].inspection_p50_ms}});
    }
    send_json(res, {{"period_s", opt_.history_period_s}, {"samples", out}});
  });
  s.Get("/api/fillets", [this](const httplib::Request& req, httplib::Response& res) {
    const FilletQuery q = fillet_query(req.params);
    json list = json::array();
    int64_t last = q.after;
    for (const StoredFillet& f : store_.list_fillets(q)) {
      list.push_back(fillet_json(f));
      list.back()["images"] = image_kinds(store_, f.uid);
      last = std::max(last, f.uid);
    }
    // `next_after` continues the search where this page ended.
    send_json(res, {{"fillets", list}, {"next_after", last}});
  });
  s.Get("/api/fillets.csv", [this](const httplib::Request& req, httplib::Response& res) {
    FilletQuery q = fillet_query(req.params);
    q.limit = 5000;
    std::string csv = fillet_csv_header();
    while (true) {
      const std::vector<StoredFillet> page = store_.list_fillets(q);
      for (const StoredFillet& f : page) csv += fillet_csv_row(f);
      if (int(page.size()) < q.limit) break;
      q.after = page.back().uid;
    }
    res.set_header("Content-Disposition", "attachment; filename=\"rangex-fillets.csv\"");
    res.set_content(csv, "text/csv");
  });
  s.Get(R"(/api/fillets/(\d+))", [this](const httplib::Request& req, httplib::Response& res) {
    const int64_t uid = parse_uid(req.matches[1]);
    const std::optional<StoredFillet> f = store_.fillet(uid);
    if (!f) throw NotFound("no fillet " + std::to_string(uid) + " in the store");
    json j = fillet_json(*f);
    j["images"] = image_kinds(store_, uid);
    send_json(res, j);
  });
  s.Get(R"(/api/fillets/(\d+)/images/([a-z_]+))",
        [this](const httplib::Request& req, httplib::Response& res) {
          const int64_t uid = parse_uid(req.matches[1]);
          const std::string kind = checked_image_kind(req.matches[2]);
          const std::optional<std::string> path = store_.image_path(uid, kind);
          if (!path)
            throw NotFound("fillet " + std::to_string(uid) + " has no " + kind +
                           " image (images are kept for rejects and fillets not inspected)");
          std::string body;
          if (kind == "overlay" || req.get_param_value("raw") == "1") {
            std::ifstream in(*path, std::ios::binary);
            if (!in) throw NotFound("image file " + *path + " is missing");
            body.assign(std::istreambuf_iterator<char>(in), {});
          } else {
            body = display_png(*path, kind);
          }
          res.set_header("Cache-Control", "max-age=3600");
          res.set_content(body, "image/png");
        });
  s.Get("/api/calibrations", [this](const httplib::Request& req, httplib::Response& res) {
    const int lane = int(int_param(req.params, "lane", -1, -1, 1 << 20));
    json versions = json::array();
    for (const StoredCalibration& c : store_.calibrations(lane))
      versions.push_back({{"lane", c.lane},
                          {"id", c.id},
                          {"uploaded_ns", c.uploaded_ns},
                          {"active", c.active},
                          {"has_report", !c.report.empty()}});
    json events = json::array();
    for (const AuditEntry& e : store_.audit_entries(100000))
      if (e.what.rfind("calibration.", 0) == 0)
        events.push_back(
            {{"ts_ns", e.ts_ns}, {"who", e.who}, {"what", e.what}, {"detail", e.detail}});
    send_json(res, {{"versions", versions}, {"events", events}});
  });
  s.Get("/api/audit", [this](const httplib::Request& req, httplib::Response& res) {
    const int limit = int(int_param(req.params, "limit", 200, 1, 100000));
    json out = json::array();
    for (const AuditEntry& e : store_.audit_entries(limit))
      out.push_back({{"ts_ns", e.ts_ns}, {"who", e.who}, {"what", e.what}, {"detail", e.detail}});
    send_json(res, out);
  });
  s.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    MetricsInput m;
    m.stats = engine_.stats();
    m.lanes = engine_.lanes();
    m.subscribers = hub_.subscribers();
    m.ingest_streams = opt_.ingest_streams ? opt_.ingest_streams() : 0;
    m.http_clients = event_streams_;
    res.set_content(prometheus_text(m), "text/plain; version=0.0.4; charset=utf-8");
  });
  s.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
    const std::set<std::string> decisions = decision_set(req.params, "decisions");
    const std::set<int> lanes = int_set(req.params, "lanes");
    auto client = std::make_shared<EventClient>();
    client->fd = GatedHttpServer::current_fd();
    {
      std::lock_guard<std::mutex> lock(events_mu_);
      if (int(event_clients_.size()) >= opt_.max_event_streams) {
        // Full: the stream furthest behind gives way, if one is behind at all (a client
        // that stopped reading); streams that keep up are never cut for a newcomer.
        auto behind = event_clients_.end();
        int most = 0;
        for (auto it = event_clients_.begin(); it != event_clients_.end(); ++it)
          if (const int q = unread_bytes((*it)->fd); q > most) most = q, behind = it;
        if (behind == event_clients_.end()) {
          res.status = 503;
          // The client closes the connection: kept alive, each refusal held one of the few
          // threads for the keep-alive timeout (168 of them once blocked /api/statistics).
          res.set_header("Connection", "close");
          res.set_content(json{{"error", "too many event streams (" +
                                             std::to_string(opt_.max_event_streams) + ")"}}
                              .dump(),
                          "application/json");
          return;
        }
        (*behind)->evicted = true;
        {
          std::lock_guard<std::mutex> ring((*behind)->mu);
          (*behind)->rung = true;
        }
        (*behind)->cv.notify_all();
        event_clients_.erase(behind);
        ++events_dropped_;
      }
      event_clients_.push_back(client);
      event_streams_ = int(event_clients_.size());
    }
    if (client->fd >= 0)
      ::setsockopt(client->fd, SOL_SOCKET, SO_SNDBUF, &kEventSendBuffer, sizeof kEventSendBuffer);
    std::weak_ptr<EventClient> weak = client;
    client->sub = hub_.subscribe(lanes, decisions, 256, [weak] {
      if (auto c = weak.lock()) {
        std::lock_guard<std::mutex> lock(c->mu);
        c->rung = true;
        c->cv.notify_all();
      }
    });
    res.set_header("Cache-Control", "no-cache");
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, client, last_beat = std::chrono::steady_clock::now()](
            size_t, httplib::DataSink& sink) mutable {
          {
            std::unique_lock<std::mutex> lock(client->mu);
            client->cv.wait_for(lock, std::chrono::milliseconds(500), [&] { return client->rung; });
            client->rung = false;
          }
          if (stopping_ || client->evicted || !sink.is_writable()) return false;
          StoredFillet f;
          uint64_t lagged = 0;
          std::string out;
          while (hub_.take(client->sub, f, lagged)) {
            json j = fillet_json(f);
            j["images"] = image_kinds(store_, f.uid);
            // Results this client lost (it fell behind its 256) before this one.
            j["lagged"] = lagged;
            out += "event: fillet\ndata: " + j.dump() + "\n\n";
          }
          if (hub_.closed(client->sub)) {
            if (!out.empty()) sink.write(out.data(), out.size());
            sink.done();
            return true;
          }
          const auto now = std::chrono::steady_clock::now();
          if (out.empty() && now - last_beat > kBeatPeriod)
            out = ": " + std::string(kBeatBytes, ' ') + "\n\n";  // a comment: not an event
          if (!out.empty()) {
            last_beat = now;
            if (!sink.write(out.data(), out.size())) return false;
          }
          return true;
        },
        [this, client](bool) {
          hub_.unsubscribe(client->sub);
          std::lock_guard<std::mutex> lock(events_mu_);
          const auto it = std::find(event_clients_.begin(), event_clients_.end(), client);
          if (it != event_clients_.end()) event_clients_.erase(it);
          event_streams_ = int(event_clients_.size());
        });
  });
}

}  // namespace rangex
