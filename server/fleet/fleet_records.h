// What the fleet view reads from the plant-wide PostgreSQL: every server's row (health,
// forwarding lag), fillets across servers in one order, lane settings' history, the audit
// log and the plant's last hour. Plain types; the HTTP routes turn them into JSON.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "store/store.h"

namespace rangex {

class PgConnection;

struct FleetServerRow {
  std::string id, host, http, health;  // health: the server's JSON text
  int64_t started_ns = 0, seen_ns = 0, head_seq = 0, forwarded_seq = 0, lag_records = 0;
  double lag_seconds = 0;
};

// Fillets across servers are ordered by (decided_ns, server, uid): a page continues after
// the last one's position, written "DECIDED_NS.SERVER.UID" (server ids hold no '/').
struct FleetCursor {
  int64_t decided_ns = -1;  // -1: from the start
  std::string server;
  int64_t uid = 0;
  std::string text() const;
  // "" or "0": from the start; anything else must read back (throws BadRequest).
  static FleetCursor parse(const std::string& s);
};

struct FleetQuery {
  std::string server;  // "" every server
  FilletQuery q;       // lane, decision, time, limit, newest (q.after unused)
  FleetCursor after;
};

struct FleetFillet {
  std::string server;
  StoredFillet f;
  std::vector<std::string> images;  // kinds its server keeps
};

struct FleetSetting {
  std::string server, kind, id;  // kind: calibration | learned
  int lane = 0;
  int64_t uploaded_ns = 0;
  bool active = false, has_report = false;
};

struct FleetAudit {
  std::string server;
  int64_t row = 0;
  AuditEntry e;
};

struct FleetBucket {
  int64_t t_ns = 0;
  int64_t fillets = 0, rejects = 0, not_inspected = 0;
};

std::vector<FleetServerRow> fleet_servers(PgConnection& db);
std::optional<FleetServerRow> fleet_server(PgConnection& db, const std::string& id);
std::vector<FleetFillet> fleet_fillets(PgConnection& db, const FleetQuery& fq);
std::optional<FleetFillet> fleet_fillet(PgConnection& db, const std::string& server, int64_t uid);
std::vector<FleetSetting> fleet_settings(PgConnection& db, int lane);
// The newest `limit` entries, newest last; `what_prefixes` non-empty: only those.
std::vector<FleetAudit> fleet_audit(PgConnection& db, int limit,
                                    const std::vector<std::string>& what_prefixes = {});
// Fillets decided per bucket since `since_ns`, every server together.
std::vector<FleetBucket> fleet_history(PgConnection& db, int64_t since_ns, int64_t bucket_ns);

}  // namespace rangex
