// Live decisions as server-sent events (/api/events): one bounded hub subscription per
// client, woken by the hub; a full house gives the stream furthest behind's place to a
// newcomer, never one that keeps up.
#include <httplib.h>
#include <linux/sockios.h>
#include <sys/ioctl.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <set>

#include "core/json_text.h"
#include "service/gated_http_server.h"
#include "service/http_json.h"
#include "service/http_params.h"
#include "service/http_server.h"

namespace rangex {

using json = nlohmann::json;

namespace {
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

void HttpServer::event_routes(httplib::Server& s) {
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
          res.set_content(
              json_dump(json{{"error", "too many event streams (" +
                                           std::to_string(opt_.max_event_streams) + ")"}}),
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
        hub_.note_dropped();
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
            out += "event: fillet\ndata: " + json_dump(j) + "\n\n";
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
