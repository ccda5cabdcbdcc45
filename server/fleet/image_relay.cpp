#include "fleet/image_relay.h"

#include <httplib.h>

#include <nlohmann/json.hpp>

#include "core/json_text.h"

namespace rangex {

namespace {
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
  const httplib::Result got = c.Get(r.path.c_str(), h);
  if (!got)
    return refusal(502, r.server,
                   "server " + r.server + " at " + r.url + " is unreachable (" +
                       httplib::to_string(got.error()) + "); the image stays on that server",
                   true);
  return {got->status, got->body, got->get_header_value("Content-Type")};
}

}  // namespace rangex
