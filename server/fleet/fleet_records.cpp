#include "fleet/fleet_records.h"

#include <algorithm>
#include <map>

#include "plantdb/pg_array.h"
#include "plantdb/pg_connection.h"
#include "plantdb/pg_records.h"
#include "service/http_params.h"

namespace rangex {

std::string FleetCursor::text() const {
  return std::to_string(decided_ns) + "." + server + "." + std::to_string(uid);
}

FleetCursor FleetCursor::parse(const std::string& s) {
  FleetCursor c;
  if (s.empty() || s == "0") return c;
  const size_t a = s.find('.'), b = s.rfind('.');
  if (a == std::string::npos || b == a)
    throw BadRequest("after '" + s + "': expected DECIDED_NS.SERVER.UID (a page's next_after)");
  c.decided_ns = parse_int("after", s.substr(0, a), 0, INT64_MAX);
  c.server = s.substr(a + 1, b - a - 1);
  c.uid = parse_int("after", s.substr(b + 1), 0, INT64_MAX);
  return c;
}

namespace {
constexpr const char* kServerColumns =
    "SELECT server_id, host, http, health, started_ns, seen_ns, head_seq, forwarded_seq, "
    "lag_records, lag_seconds FROM servers";

std::vector<FleetServerRow> server_rows(const PgRows& r) {
  std::vector<FleetServerRow> out;
  for (int i = 0; i < r.rows(); ++i)
    out.push_back({r.str(i, 0), r.str(i, 1), r.str(i, 2), r.str(i, 3), r.i64(i, 4), r.i64(i, 5),
                   r.i64(i, 6), r.i64(i, 7), r.i64(i, 8), r.dbl(i, 9)});
  return out;
}
}  // namespace

std::vector<FleetServerRow> fleet_servers(PgConnection& db) {
  return server_rows(db.exec(std::string(kServerColumns) + " ORDER BY server_id"));
}

std::optional<FleetServerRow> fleet_server(PgConnection& db, const std::string& id) {
  std::vector<FleetServerRow> r =
      server_rows(db.exec(std::string(kServerColumns) + " WHERE server_id = $1", {id}));
  if (r.empty()) return std::nullopt;
  return std::move(r.front());
}

namespace {
// Each listed fillet in full (fragments, image kinds), in the listing's order.
std::vector<FleetFillet> complete(PgConnection& db,
                                  const std::vector<std::pair<std::string, int64_t>>& keys) {
  std::map<std::string, std::vector<int64_t>> by_server;
  for (const auto& [s, uid] : keys) by_server[s].push_back(uid);
  std::map<std::pair<std::string, int64_t>, FleetFillet> found;
  for (const auto& [s, uids] : by_server) {
    for (auto& [uid, f] : pg_fillets(db, s, uids)) found[{s, uid}] = {s, std::move(f), {}};
    PgArray ids;
    for (int64_t u : uids) ids.add(u);
    const PgRows im = db.exec(
        "SELECT fillet_uid, kind FROM images WHERE server_id = $1 AND fillet_uid = "
        "ANY($2::bigint[]) ORDER BY fillet_uid, kind",
        {s, ids.text()});
    for (int i = 0; i < im.rows(); ++i)
      if (auto it = found.find({s, im.i64(i, 0)}); it != found.end())
        it->second.images.push_back(im.str(i, 1));
  }
  std::vector<FleetFillet> out;
  for (const auto& k : keys)
    if (auto it = found.find(k); it != found.end()) out.push_back(std::move(it->second));
  return out;
}
}  // namespace

std::vector<FleetFillet> fleet_fillets(PgConnection& db, const FleetQuery& fq) {
  const FilletQuery& q = fq.q;
  const bool newest = q.newest_first;
  std::string sql =
      "SELECT server_id, uid FROM fillets WHERE ($1 = '' OR server_id = $1) AND ($2::int < 0 OR "
      "lane = $2::int) AND ($3 = '' OR decision = $3) AND decided_ns >= $4::bigint AND "
      "($5::bigint = 0 OR decided_ns < $5::bigint)";
  if (!newest) sql += " AND (decided_ns, server_id, uid) > ($6::bigint, $7, $8::bigint)";
  sql += newest ? " ORDER BY decided_ns DESC, server_id DESC, uid DESC LIMIT $6::int"
                : " ORDER BY decided_ns, server_id, uid LIMIT $9::int";
  std::vector<PgParam> p = {fq.server, std::to_string(q.lane), q.decision,
                            std::to_string(q.from_ns), std::to_string(q.to_ns)};
  if (!newest) {
    p.push_back(std::to_string(fq.after.decided_ns));
    p.push_back(fq.after.server);
    p.push_back(std::to_string(fq.after.uid));
  }
  p.push_back(std::to_string(q.limit));
  const PgRows r = db.exec(sql, p);
  std::vector<std::pair<std::string, int64_t>> keys;
  for (int i = 0; i < r.rows(); ++i) keys.push_back({r.str(i, 0), r.i64(i, 1)});
  return complete(db, keys);
}

std::optional<FleetFillet> fleet_fillet(PgConnection& db, const std::string& server, int64_t uid) {
  std::vector<FleetFillet> f = complete(db, {{server, uid}});
  if (f.empty()) return std::nullopt;
  return std::move(f.front());
}

std::vector<FleetSetting> fleet_settings(PgConnection& db, int lane) {
  const PgRows r = db.exec(
      "SELECT server_id, kind, lane, id, uploaded_ns, active, report <> '' FROM settings WHERE "
      "$1::int < 0 OR lane = $1::int ORDER BY server_id, lane, kind, uploaded_ns",
      {std::to_string(lane)});
  std::vector<FleetSetting> out;
  for (int i = 0; i < r.rows(); ++i)
    out.push_back({r.str(i, 0), r.str(i, 1), r.str(i, 3), int(r.i64(i, 2)), r.i64(i, 4),
                   r.str(i, 5) == "t", r.str(i, 6) == "t"});
  return out;
}

std::vector<FleetAudit> fleet_audit(PgConnection& db, int limit,
                                    const std::vector<std::string>& what_prefixes) {
  PgArray patterns;
  for (const std::string& w : what_prefixes) patterns.add(w + "%");
  const PgRows r = db.exec(
      "SELECT server_id, row_id, ts_ns, who, what, detail FROM audit WHERE "
      "cardinality($2::text[]) = 0 OR what LIKE ANY($2::text[]) ORDER BY ts_ns DESC, server_id "
      "DESC, row_id DESC LIMIT $1::int",
      {std::to_string(limit), patterns.text()});
  std::vector<FleetAudit> out;
  for (int i = r.rows() - 1; i >= 0; --i)
    out.push_back({r.str(i, 0), r.i64(i, 1), {r.i64(i, 2), r.str(i, 3), r.str(i, 4), r.str(i, 5)}});
  return out;
}

std::vector<FleetBucket> fleet_history(PgConnection& db, int64_t since_ns, int64_t bucket_ns) {
  const PgRows r = db.exec(
      "SELECT (decided_ns / $2::bigint) * $2::bigint AS t, count(*), count(*) FILTER (WHERE "
      "decision = 'reject'), count(*) FILTER (WHERE decision = 'not_inspected') FROM fillets "
      "WHERE decided_ns >= $1::bigint GROUP BY t ORDER BY t",
      {std::to_string(since_ns), std::to_string(bucket_ns)});
  std::vector<FleetBucket> out;
  for (int i = 0; i < r.rows(); ++i)
    out.push_back({r.i64(i, 0), r.i64(i, 1), r.i64(i, 2), r.i64(i, 3)});
  return out;
}

}  // namespace rangex
