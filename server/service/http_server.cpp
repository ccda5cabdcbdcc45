#include "service/http_server.h"

#include <httplib.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "service/gated_http_server.h"
#include "service/http_front.h"
#include "service/http_json.h"

namespace rangex {

using json = nlohmann::json;

HttpServer::HttpServer(Engine& engine, Store& store, ResultsHub& hub, HttpOptions opt)
    : engine_(engine), store_(store), hub_(hub), opt_(std::move(opt)), access_(opt_.security) {
  check_listen_security(opt_.listen, opt_.security, "the dashboard");
  // Event streams hold a worker each while open: the gate has room for all of them and for
  // the ordinary requests beside them.
  HttpFront front =
      make_http_front(opt_.listen, opt_.security, opt_.max_event_streams + 8, "plant.http");
  gate_ = &front.server->gate();
  host_ = front.host;
  guard_http(*front.server, access_);
  serve_dashboard_files(*front.server);
  routes(*front.server);
  port_ = bind_http_front(front, opt_.listen, "plant.http");
  http_ = std::move(front.server);
  history_.add(PlantHistory::sample(engine_.stats(), engine_.lanes(), now_ns()));
  listener_ = listen_in_background(*http_);
  sampler_ = std::thread([this] { sampler(); });
}

HttpServer::~HttpServer() {
  stop();
}

std::string HttpServer::address() const {
  return host_ + ":" + std::to_string(port_);
}

std::string HttpServer::health_text() {
  return server_health_text(engine_, history_, opt_.version);
}

std::string HttpServer::url() const {
  std::string host = host_;
  if (host.empty() || host == "0.0.0.0" || host == "::" || host == "[::]") {
    char buf[256] = {};
    host = gethostname(buf, sizeof buf - 1) == 0 && buf[0] ? buf : "localhost";
  }
  return std::string(tls() ? "https" : "http") + "://" + host + ":" + std::to_string(port_);
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
    history_.add(PlantHistory::sample(engine_.stats(), engine_.lanes(), now_ns()));
  }
}

Identity HttpServer::identify(const httplib::Request& req) const {
  return identify_request(access_, req);
}

void HttpServer::routes(httplib::Server& s) {
  plant_routes(s);
  fillet_routes(s);
  record_routes(s);
  event_routes(s);
  lane_action_routes(s);
}

}  // namespace rangex
