#include "fleet/image_relay.h"

#include <httplib.h>

#include <condition_variable>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "core/json_text.h"

namespace rangex {

namespace {

// No fillet's image comes near it: a record of 480 pixels x 4,000 lines of 16 bits is 4 MB.
constexpr size_t kMaxRelayedImageBytes = size_t(64) << 20;

std::string seconds_text(double s) {
  std::ostringstream os;
  os << s;
  return os.str();
}

RelayedImage refusal(int status, const std::string& server, const std::string& why,
                     bool unreachable) {
  return {
      status,
      json_dump(nlohmann::json{{"error", why}, {"server", server}, {"unreachable", unreachable}}),
      "application/json"};
}
}  // namespace

RelayedImage relay_image(const ImageRelayRequest& r) {
  if (r.url.empty())
    return refusal(503, r.server,
                   "server " + r.server +
                       " keeps this image but serves no dashboard (plant.http off), so the "
                       "fleet view cannot fetch it",
                   true);
  if (r.url.rfind("http://", 0) != 0 && r.url.rfind("https://", 0) != 0)
    return refusal(502, r.server,
                   "server " + r.server + " gave no usable address ('" + r.url + "')", true);
  httplib::Client c(r.url);
  if (!c.is_valid())
    return refusal(502, r.server,
                   "server " + r.server + " gave no usable address ('" + r.url + "')", true);
  const auto whole = std::chrono::duration<double>(r.timeout_s);
  const auto s = std::chrono::duration_cast<std::chrono::seconds>(whole);
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(whole - s);
  c.set_connection_timeout(s.count(), us.count());
  c.set_read_timeout(s.count(), us.count());
  c.set_write_timeout(s.count(), us.count());
  if (!r.ca_file.empty()) c.set_ca_cert_path(r.ca_file.c_str());
  c.enable_server_certificate_verification(true);
  httplib::Headers h;
  if (!r.authorization.empty()) h.emplace("Authorization", r.authorization);
  // The read timeout bounds each read, not the answer: a dashboard sending a byte at a time
  // would hold this fleet worker for as long as it liked. A watchdog ends the request at the
  // deadline, and the body is bounded as it arrives.
  std::mutex mu;
  std::condition_variable cv;
  bool done = false, expired = false, too_large = false;
  std::thread watchdog([&] {
    std::unique_lock<std::mutex> lk(mu);
    if (!cv.wait_for(lk, whole, [&] { return done; })) {
      expired = true;
      c.stop();  // thread-safe: shuts the socket down under the reading thread
    }
  });
  std::string body;
  const httplib::Result got = c.Get(r.path.c_str(), h, [&](const char* data, size_t n) {
    if (body.size() + n > kMaxRelayedImageBytes) return !(too_large = true);
    body.append(data, n);
    return true;
  });
  {
    std::lock_guard<std::mutex> lk(mu);
    done = true;
  }
  cv.notify_all();
  watchdog.join();
  const std::string at = "server " + r.server + " at " + r.url;
  if (too_large)
    return refusal(502, r.server,
                   at + " sent more than " + std::to_string(kMaxRelayedImageBytes >> 20) +
                       " MiB for one image (no fillet's image is that large); refused",
                   false);
  if (expired)
    return refusal(502, r.server,
                   at + " did not send the image within " + seconds_text(r.timeout_s) +
                       " s; the image stays on that server",
                   true);
  if (!got)
    return refusal(502, r.server,
                   at + " is unreachable (" + httplib::to_string(got.error()) +
                       "); the image stays on that server",
                   true);
  return {got->status, std::move(body), got->get_header_value("Content-Type")};
}

}  // namespace rangex
