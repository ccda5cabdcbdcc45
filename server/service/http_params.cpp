#include "service/http_params.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string_view>

#include "service/image_view.h"

namespace rangex {

namespace {
const std::string* value(const QueryParams& p, const char* name) {
  const auto it = p.find(name);
  return it == p.end() ? nullptr : &it->second;
}
}  // namespace

int64_t parse_int(const char* name, const std::string& v, int64_t lo, int64_t hi) {
  // Digits after one optional sign, nothing else: std::stoll took " 2" (a leading space).
  std::string_view s(v);
  const bool plus = !s.empty() && s[0] == '+';
  if (plus) s.remove_prefix(1);  // from_chars reads '-' but not '+'
  const size_t first = !plus && !s.empty() && s[0] == '-' ? 1 : 0;
  const bool digits = s.size() > first && std::all_of(s.begin() + first, s.end(),
                                                      [](char c) { return c >= '0' && c <= '9'; });
  if (!digits) throw BadRequest(std::string(name) + " must be an integer (got '" + v + "')");
  int64_t n = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), n);
  if (r.ec != std::errc() || n < lo || n > hi)
    throw BadRequest(std::string(name) + " must be within " + std::to_string(lo) + ".." +
                     std::to_string(hi) + " (got " + v + ")");
  return n;
}

int64_t int_param(const QueryParams& p, const char* name, int64_t fallback, int64_t lo,
                  int64_t hi) {
  const std::string* v = value(p, name);
  return v ? parse_int(name, *v, lo, hi) : fallback;
}

const std::string& checked_decision(const char* name, const std::string& d) {
  if (d != "pass" && d != "reject" && d != "not_inspected")
    throw BadRequest(std::string(name) + " must be pass, reject or not_inspected (got '" + d +
                     "')");
  return d;
}

FilletQuery fillet_query(const QueryParams& p) {
  FilletQuery q;
  q.lane = int(int_param(p, "lane", -1, -1, 1 << 20));
  q.from_ns = int_param(p, "from_ns", 0, 0, INT64_MAX);
  q.to_ns = int_param(p, "to_ns", 0, 0, INT64_MAX);
  q.after = int_param(p, "after", 0, 0, INT64_MAX);
  q.limit = int(int_param(p, "limit", 200, 1, 10000));
  q.newest_first = int_param(p, "newest", 0, 0, 1) == 1;
  if (const std::string* d = value(p, "decision"); d && !d->empty())
    q.decision = checked_decision("decision", *d);
  return q;
}

namespace {
template <typename F>
void each_item(const QueryParams& p, const char* name, F&& f) {
  const std::string* v = value(p, name);
  if (!v) return;
  std::stringstream ss(*v);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) f(item);
}
}  // namespace

std::set<int> int_set(const QueryParams& p, const char* name) {
  std::set<int> out;
  each_item(p, name, [&](const std::string& s) {
    out.insert(int(parse_int(name, s, INT32_MIN, INT32_MAX)));
  });
  return out;
}

std::set<std::string> decision_set(const QueryParams& p, const char* name) {
  std::set<std::string> out;
  each_item(p, name, [&](const std::string& s) { out.insert(checked_decision(name, s)); });
  return out;
}

int64_t parse_uid(const std::string& digits) {
  return parse_int("the fillet uid", digits, 1, INT64_MAX);
}

const std::string& checked_image_kind(const std::string& kind) {
  if (!is_image_kind(kind))
    throw BadRequest(
        "image kind must be overlay, xray, xray_high, thickness, pseudo_xray, residual, bone or "
        "fat_share (got '" +
        kind + "')");
  return kind;
}

VerificationRequest verification_body(const std::string& body) {
  const nlohmann::json j = nlohmann::json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    throw BadRequest("the body must be a JSON object {\"piece\": ..., \"x_mm\": ...}");
  for (const auto& [key, v] : j.items())
    if (key != "piece" && key != "x_mm" && key != "tolerance_mm" && key != "fillets")
      throw BadRequest("unknown field '" + key + "' (piece, x_mm, tolerance_mm, fillets)");
  VerificationRequest r;
  if (!j.contains("piece") || !j["piece"].is_string() || j["piece"].get<std::string>().empty())
    throw BadRequest("piece must be the test piece's name, e.g. \"2 mm calcified sphere\"");
  r.piece = j["piece"].get<std::string>();
  auto number = [&](const char* name, bool required) -> double {
    if (!j.contains(name)) {
      if (required) throw BadRequest(std::string(name) + " is required (millimetres)");
      return 0;
    }
    if (!j[name].is_number() || !std::isfinite(j[name].get<double>()))
      throw BadRequest(std::string(name) + " must be a number");
    return j[name].get<double>();
  };
  r.x_mm = number("x_mm", true);
  r.tolerance_mm = number("tolerance_mm", false);
  if (j.contains("fillets")) {
    // Its range is checked where gRPC's is (Verifications::start).
    if (!j["fillets"].is_number_integer() || std::llabs(j["fillets"].get<int64_t>()) > 1000000)
      throw BadRequest("fillets must be an integer (1..1000)");
    r.fillets = int(j["fillets"].get<int64_t>());
  }
  return r;
}

}  // namespace rangex
