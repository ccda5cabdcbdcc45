// The HTTP API's list, image and event queries as a browser, a script or an attacker could
// send them: a query string (and a path's uid and image kind) checked by service/http_params
// and run against a small store. Refusals are BadRequest (400); what is accepted runs, and
// every fillet the store returns matches the query (lane, decision, time range, limit).
// Input: "uid/kind?name=value&name=value..." as raw bytes (no percent-decoding). The same
// bytes are also a dashboard action's JSON body (verification_body: a request or a
// BadRequest) and a connection's first bytes at the HTTP gate (request_end: where the
// request ends, never past what arrived unless waiting, never a body over the bound).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "core/error.h"
#include "service/http_params.h"
#include "service/request_end.h"
#include "store/store.h"

using namespace rangex;
namespace fs = std::filesystem;

namespace {
Store& store() {
  static const fs::path dir =
      fs::temp_directory_path() / ("rangex-fuzz-query-" + std::to_string(getpid()));
  static Store* s = [] {
    fs::remove_all(dir);
    auto* st = new Store(dir.string());
    const char* decisions[] = {"pass", "reject", "not_inspected"};
    for (int k = 0; k < 24; ++k) {
      StoredFillet f;
      f.lane = k % 4;
      f.decision = decisions[k % 3];
      f.decided_ns = 1000 * (k + 1);
      f.first_encoder = 100 * k;
      f.rows = 50;
      if (k % 3 == 1) f.fragments.push_back({"bone", 1, 2, 3, 9, 1, 4});
      st->add_fillet(f);
    }
    return st;
  }();
  return *s;
}

QueryParams parse_query(const std::string& q) {
  QueryParams p;
  size_t at = 0;
  while (at <= q.size()) {
    size_t amp = q.find('&', at);
    if (amp == std::string::npos) amp = q.size();
    const std::string item = q.substr(at, amp - at);
    const size_t eq = item.find('=');
    if (!item.empty())
      p.emplace(item.substr(0, eq), eq == std::string::npos ? "" : item.substr(eq + 1));
    at = amp + 1;
  }
  return p;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  const size_t qm = input.find('?');
  const std::string path = input.substr(0, qm);
  const QueryParams p = parse_query(qm == std::string::npos ? "" : input.substr(qm + 1));
  Store& st = store();
  try {
    const FilletQuery q = fillet_query(p);
    const auto list = st.list_fillets(q);
    if (int(list.size()) > q.limit) std::abort();
    for (const StoredFillet& f : list) {
      if (q.lane >= 0 && f.lane != q.lane) std::abort();
      if (!q.decision.empty() && f.decision != q.decision) std::abort();
      if (f.decided_ns < q.from_ns || (q.to_ns && f.decided_ns >= q.to_ns)) std::abort();
      if (!q.newest_first && f.uid <= q.after) std::abort();
    }
  } catch (const BadRequest&) {
  }
  try {
    int_set(p, "lanes");
    decision_set(p, "decisions");
    int_param(p, "minutes", 60, 1, 60);
    st.audit_entries(int(int_param(p, "limit", 200, 1, 100000)));
  } catch (const BadRequest&) {
  }
  try {
    const size_t slash = path.find('/');
    const int64_t uid = parse_uid(path.substr(0, slash));
    if (uid < 1) std::abort();
    const auto f = st.fillet(uid);
    if (f && f->uid != uid) std::abort();
    if (slash != std::string::npos) st.image_path(uid, checked_image_kind(path.substr(slash + 1)));
  } catch (const BadRequest&) {
  }
  try {
    const VerificationRequest r = verification_body(input);
    if (r.piece.empty()) std::abort();
  } catch (const BadRequest&) {
  }
  constexpr size_t kHead = 256, kBody = 64;
  const RequestEnd e = request_end(input, kHead, kBody);
  if (e.complete && (e.too_large || e.bytes > input.size())) std::abort();
  if (e.complete) {
    const size_t head = input.find("\r\n\r\n") + 4;
    if (head > kHead + 4 || e.bytes < head || e.bytes - head > kBody) std::abort();
  }
  return 0;
}
