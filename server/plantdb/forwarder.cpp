#include "plantdb/forwarder.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "plantdb/pg_array.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"
#include "store/store.h"

namespace rangex {

std::string host_name() {
  char buf[256] = {};
  if (gethostname(buf, sizeof buf - 1) != 0 || !buf[0]) return "rangexd";
  return buf;
}

std::string utc_day(int64_t ns) {
  const std::time_t s = std::time_t(ns >= 0 ? ns / 1000000000 : (ns - 999999999) / 1000000000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[16];
  std::strftime(buf, sizeof buf, "%Y-%m-%d", &tm);
  return buf;
}

Forwarder::Forwarder(Store& store, ForwarderOptions opt) : store_(store), opt_(std::move(opt)) {
  if (opt_.server_id.empty()) fail("plant.server_id: empty (it names this server's records)");
  status_.state = "starting";
  status_.server_id = opt_.server_id;
  status_.database = pg_where(opt_.conninfo);  // refuses a string libpq cannot read
}

Forwarder::~Forwarder() {
  stop();
}

void Forwarder::start() {
  store_.hold_unforwarded(true);
  thread_ = std::thread([this] { run(); });
}

void Forwarder::stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  {
    // A statement may wait on a database that answers nothing: it fails now, not never.
    std::lock_guard<std::mutex> lock(db_mu_);
    interrupted_ = true;
    if (db_) db_->interrupt();
  }
  if (thread_.joinable()) thread_.join();
  set_db(nullptr);
}

void Forwarder::set_db(std::unique_ptr<PgConnection> db) {
  std::lock_guard<std::mutex> lock(db_mu_);
  if (db && interrupted_) db->interrupt();
  db_ = std::move(db);
}

ForwarderStatus Forwarder::status() const {
  std::lock_guard<std::mutex> lock(mu_);
  return status_;
}

bool Forwarder::wait_caught_up(double timeout_s) {
  const int64_t head = store_.head_seq();
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::unique_lock<std::mutex> lock(mu_);
  return cv_.wait_until(lock, until, [&] {
    return status_.forwarded_seq >= head && status_.lag_records == 0 && status_.connected;
  });
}

void Forwarder::describe(const std::string& http_url, std::function<std::string()> health) {
  std::lock_guard<std::mutex> lock(mu_);
  http_url_ = http_url;
  health_ = std::move(health);
}

void Forwarder::connect() {
  set_db(nullptr);
  set_db(std::make_unique<PgConnection>(opt_.conninfo, opt_.connect_timeout_s,
                                        opt_.statement_timeout_s));
  PgConnection* db = db_.get();
  require_plant_db_schema(*db);
  const std::string id = opt_.server_id;
  // The server id is this process's while its session lives: a second rangexd with the
  // same id is refused by the database itself.
  if (db->exec("SELECT pg_try_advisory_lock(hashtext($1)::bigint)", {"rangex server " + id})
          .str(0, 0) != "t") {
    const PgRows r = db->exec("SELECT host, started_ns FROM servers WHERE server_id = $1", {id});
    throw FailedPrecondition(join("plant.server_id '", id,
                                  "' is already forwarding from another rangexd",
                                  r.rows() ? " (host " + r.str(0, 0) + ")" : std::string(),
                                  ": two servers cannot share an id; give this one its own"));
  }
  const std::string now = std::to_string(now_ns());
  db->exec(
      "INSERT INTO servers (server_id, host, started_ns, seen_ns) VALUES ($1, $2, $3, $3) ON "
      "CONFLICT (server_id) DO UPDATE SET host = excluded.host, started_ns = "
      "excluded.started_ns, seen_ns = excluded.seen_ns",
      {id, opt_.host, now});
  const PgRows c = db->exec(
      "SELECT forwarded_seq, image_seq, calibration_row, learned_row FROM servers WHERE "
      "server_id = $1",
      {id});
  ForwardCursor held{c.i64(0, 0), c.i64(0, 1), c.i64(0, 2), c.i64(0, 3)};
  // The database's records of this id must be this store's: a store started afresh under
  // an old id would otherwise have its first records taken for ones already there.
  if (held.seq > 0) {
    const PgRows h = db->exec("SELECT hash FROM ledger WHERE server_id = $1 AND seq = $2",
                              {id, std::to_string(held.seq)});
    const std::optional<std::string> mine = store_.link_hash(held.seq);
    const int64_t head = store_.head_seq();
    if (head < held.seq || (mine && h.rows() && *mine != h.str(0, 0)))
      throw FailedPrecondition(join("PostgreSQL holds ", held.seq, " links of server '", id,
                                    "' that are not this store's (this store has ", head,
                                    mine && h.rows() && *mine != h.str(0, 0)
                                        ? ", and link " + std::to_string(held.seq) + " differs"
                                        : std::string(),
                                    "): a new store needs its own plant.server_id"));
  }
  cursor_ = held;
  need_active_ = true;
  store_.set_forwarded(cursor_);
  log::info("forwarding_connected", "forwarding to PostgreSQL at {} as '{}' from link {}",
            db_->where(), id, held.seq);
}

namespace {
// One writer per table: each sends all of a batch's rows as arrays in one statement.
void insert_links(PgConnection& db, const std::string& id, const std::vector<ForwardLink>& ls) {
  PgArray seq, kind, ref, ts, prev, hash, day;
  for (const ForwardLink& l : ls) {
    seq.add(l.seq), kind.add(l.kind), ref.add(l.ref), ts.add(l.ts_ns);
    prev.add(l.prev), hash.add(l.hash), day.add(utc_day(l.ts_ns));
  }
  db.exec(
      "INSERT INTO ledger SELECT $1, * FROM unnest($2::bigint[], $3::text[], $4::bigint[], "
      "$5::bigint[], $6::text[], $7::text[], $8::date[]) ON CONFLICT DO NOTHING",
      {id, seq.text(), kind.text(), ref.text(), ts.text(), prev.text(), hash.text(), day.text()});
}

// A fillet's fragments are partitioned by their fillet's day, not their own.
void insert_fillets(PgConnection& db, const std::string& id, const std::vector<StoredFillet>& fs) {
  PgArray uid, lane, lf, enc, rows, dec, reason, cal, b0, b1, b2, rm, rs, y0, ns, day;
  PgArray fu, fi, fk, fx, fy, fa, fz, fat, fm, r0, r1, c0, c1, bm, fd;
  for (const StoredFillet& f : fs) {
    const std::string fillet_day = utc_day(f.decided_ns);
    uid.add(f.uid), lane.add(int64_t(f.lane)), lf.add(f.lane_fillet), enc.add(f.first_encoder);
    rows.add(int64_t(f.rows)), dec.add(f.decision), reason.add(f.reason);
    cal.add(f.calibration_id), b0.add(f.beta0), b1.add(f.beta1), b2.add(f.beta2);
    rm.add(f.resid_mean_dn), rs.add(f.resid_std_dn), y0.add(f.belt_y0_mm);
    ns.add(f.decided_ns), day.add(fillet_day);
    for (size_t k = 0; k < f.fragments.size(); ++k) {
      const StoredFragment& g = f.fragments[k];
      fu.add(f.uid), fi.add(int64_t(k)), fk.add(g.kind), fx.add(g.x_mm), fy.add(g.y_mm);
      fa.add(g.area_mm2), fz.add(g.peak_z), fat.add(g.attenuation_mm2), fm.add(g.meat_mm);
      r0.add(int64_t(g.row0)), r1.add(int64_t(g.row1)), c0.add(int64_t(g.col0));
      c1.add(int64_t(g.col1)), bm.add(g.bone_mg), fd.add(fillet_day);
    }
  }
  db.exec(
      "INSERT INTO fillets SELECT $1, * FROM unnest($2::bigint[], $3::int[], $4::bigint[], "
      "$5::bigint[], $6::int[], $7::text[], $8::text[], $9::text[], $10::float8[], "
      "$11::float8[], $12::float8[], $13::float8[], $14::float8[], $15::float8[], "
      "$16::bigint[], $17::date[]) ON CONFLICT DO NOTHING",
      {id, uid.text(), lane.text(), lf.text(), enc.text(), rows.text(), dec.text(), reason.text(),
       cal.text(), b0.text(), b1.text(), b2.text(), rm.text(), rs.text(), y0.text(), ns.text(),
       day.text()});
  if (fu.text() != "{}")
    db.exec(
        "INSERT INTO fragments SELECT $1, * FROM unnest($2::bigint[], $3::int[], $4::text[], "
        "$5::float8[], $6::float8[], $7::float8[], $8::float8[], $9::float8[], "
        "$10::float8[], $11::int[], $12::int[], $13::int[], $14::int[], $15::float8[], "
        "$16::date[]) ON CONFLICT DO NOTHING",
        {id, fu.text(), fi.text(), fk.text(), fx.text(), fy.text(), fa.text(), fz.text(),
         fat.text(), fm.text(), r0.text(), r1.text(), c0.text(), c1.text(), bm.text(), fd.text()});
}

void insert_audit(PgConnection& db, const std::string& id,
                  const std::vector<std::pair<int64_t, AuditEntry>>& audit) {
  PgArray row, ts, who, what, detail, day;
  for (const auto& [r, e] : audit) {
    row.add(r), ts.add(e.ts_ns), who.add(e.who), what.add(e.what), detail.add(e.detail);
    day.add(utc_day(e.ts_ns));
  }
  db.exec(
      "INSERT INTO audit SELECT $1, * FROM unnest($2::bigint[], $3::bigint[], $4::text[], "
      "$5::text[], $6::text[], $7::date[]) ON CONFLICT DO NOTHING",
      {id, row.text(), ts.text(), who.text(), what.text(), detail.text(), day.text()});
}

void insert_images(PgConnection& db, const std::string& id,
                   const std::vector<ForwardImage>& images) {
  PgArray uid, kind, path, day;
  for (const ForwardImage& i : images)
    uid.add(i.uid), kind.add(i.kind), path.add(i.path), day.add(utc_day(i.decided_ns));
  // A later image of the same kind replaces the earlier reference, as in the store.
  db.exec(
      "INSERT INTO images SELECT $1, * FROM unnest($2::bigint[], $3::text[], $4::text[], "
      "$5::date[]) ON CONFLICT (server_id, fillet_uid, kind, day) DO UPDATE SET path = "
      "excluded.path",
      {id, uid.text(), kind.text(), path.text(), day.text()});
}

void insert_settings(PgConnection& db, const std::string& id,
                     const std::vector<ForwardSetting>& settings) {
  PgArray kind, lane, sid, yaml, report, ns;
  for (const ForwardSetting& s : settings) {
    kind.add(std::string(s.learned ? "learned" : "calibration")), lane.add(int64_t(s.lane));
    sid.add(s.id), yaml.add(s.yaml), report.add(s.report), ns.add(s.uploaded_ns);
  }
  db.exec(
      "INSERT INTO settings (server_id, kind, lane, id, yaml, report, uploaded_ns) SELECT "
      "$1, * FROM unnest($2::text[], $3::int[], $4::text[], $5::text[], $6::text[], "
      "$7::bigint[]) ON CONFLICT DO NOTHING",
      {id, kind.text(), lane.text(), sid.text(), yaml.text(), report.text(), ns.text()});
}

// Exactly the listed settings are active for this server; every other one is not.
void mark_active(PgConnection& db, const std::string& id,
                 const std::vector<ActiveSetting>& active) {
  PgArray kind, lane, sid;
  for (const ActiveSetting& a : active)
    kind.add(std::string(a.learned ? "learned" : "calibration")), lane.add(int64_t(a.lane)),
        sid.add(a.id);
  db.exec(
      "UPDATE settings s SET active = EXISTS (SELECT 1 FROM unnest($2::text[], $3::int[], "
      "$4::text[]) a(kind, lane, id) WHERE a.kind = s.kind AND a.lane = s.lane AND a.id = "
      "s.id) WHERE s.server_id = $1",
      {id, kind.text(), lane.text(), sid.text()});
}
}  // namespace

void Forwarder::forward(const ForwardBatch& b) {
  PgConnection& db = *db_;
  const std::string id = opt_.server_id;
  // Each record's day partition, by the time it carries.
  std::set<std::string> days;
  for (const ForwardLink& l : b.links) days.insert(utc_day(l.ts_ns));
  for (const ForwardImage& i : b.images) days.insert(utc_day(i.decided_ns));
  db.exec("BEGIN");
  try {
    for (const std::string& d : days)
      if (!days_.count(d)) db.exec("SELECT rangex_day_partitions($1::date)", {d});
    if (!b.links.empty()) insert_links(db, id, b.links);
    if (!b.fillets.empty()) insert_fillets(db, id, b.fillets);
    if (!b.audit.empty()) insert_audit(db, id, b.audit);
    if (!b.images.empty()) insert_images(db, id, b.images);
    if (!b.settings.empty()) insert_settings(db, id, b.settings);
    if (need_active_) mark_active(db, id, b.active);
    const int64_t lag = std::max<int64_t>(0, b.pending - int64_t(b.links.size()));
    // The cursor moves in the same transaction as the records: forwarded means held.
    const PgRows moved = db.exec(
        "UPDATE servers SET forwarded_seq = $2, image_seq = $3, calibration_row = $4, "
        "learned_row = $5, head_seq = $6, seen_ns = $7, lag_records = $8 WHERE server_id = $1 "
        "AND forwarded_seq = $9 RETURNING 1",
        {id, std::to_string(b.next.seq), std::to_string(b.next.image_seq),
         std::to_string(b.next.calibration_row), std::to_string(b.next.learned_row),
         std::to_string(b.head_seq), std::to_string(now_ns()), std::to_string(lag),
         std::to_string(cursor_.seq)});
    if (moved.rows() != 1)
      fail("the database's cursor of server '", id, "' moved behind this forwarder's back");
    db.exec("COMMIT");
  } catch (...) {
    db.rollback_quietly();
    throw;
  }
  days_.insert(days.begin(), days.end());
}

void Forwarder::note_lag(const ForwardBatch& b) {
  std::lock_guard<std::mutex> lock(mu_);
  status_.head_seq = b.head_seq;
  status_.forwarded_seq = cursor_.seq;
  status_.lag_records = std::max<int64_t>(0, b.head_seq - cursor_.seq);
  status_.lag_seconds = status_.lag_records > 0 && b.oldest_ns > 0
                            ? std::max(0.0, (now_ns() - b.oldest_ns) * 1e-9)
                            : 0.0;
}

void Forwarder::heartbeat(const ForwardBatch& b) {
  std::string http, health;
  std::function<std::string()> describe;
  int64_t lag_records = 0;
  double lag_seconds = 0;
  {
    std::lock_guard<std::mutex> lock(mu_);
    http = http_url_, describe = health_;
    lag_records = status_.lag_records, lag_seconds = status_.lag_seconds;
  }
  if (describe) health = describe();  // outside the lock: it reads the engine
  db_->exec(
      "UPDATE servers SET head_seq = $2, seen_ns = $3, lag_records = $4, lag_seconds = $5, "
      "http = $6, health = $7 WHERE server_id = $1",
      {opt_.server_id, std::to_string(b.head_seq), std::to_string(now_ns()),
       std::to_string(lag_records), pg_exact(lag_seconds), http, health});
}

void Forwarder::run() {
  double backoff = 1;
  auto beat = std::chrono::steady_clock::now() - std::chrono::hours(1);  // one at once
  std::string last_logged;
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (stop_) return;
    }
    double wait_s = opt_.idle_s;
    try {
      if (!db_ || !db_->ok()) connect();
      const ForwardBatch b = store_.forward_batch(cursor_, opt_.batch_links, need_active_);
      // A batch goes when it holds records, or when which settings are active may have
      // changed (at connect, and after an activation's audit entry): that goes on its own.
      if (!b.empty() || need_active_) {
        forward(b);
        cursor_ = b.next;
        need_active_ = false;
        for (const auto& [row, e] : b.audit)
          if (e.what.rfind("calibration.", 0) == 0 || e.what.rfind("learned.", 0) == 0)
            need_active_ = true;
        store_.set_forwarded(cursor_);
        std::lock_guard<std::mutex> lock(mu_);
        status_.links += int64_t(b.links.size());
        status_.images += int64_t(b.images.size());
      }
      const bool more = int(b.links.size()) == opt_.batch_links ||
                        int(b.images.size()) == opt_.batch_links || b.settings.size() > 0 ||
                        need_active_;
      // Caught up, the batch's own snapshot says where the store stood; behind, the age of
      // the oldest record still waiting needs a fresh look.
      const ForwardBatch after = more ? store_.forward_batch(cursor_, 1, false) : b;
      note_lag(after);
      // Behind or not: the fleet view reads the server's health and lag from its row.
      if (std::chrono::steady_clock::now() - beat >
          std::chrono::duration<double>(opt_.heartbeat_s)) {
        heartbeat(after);
        beat = std::chrono::steady_clock::now();
      }
      {
        std::lock_guard<std::mutex> lock(mu_);
        status_.connected = true;
        status_.state = status_.lag_records > 0 ? "forwarding" : "caught up";
        status_.last_error.clear();
      }
      cv_.notify_all();
      if (!last_logged.empty()) log::info("forwarding_resumed", "forwarding again");
      last_logged.clear();
      backoff = 1;
      if (more) continue;
    } catch (const std::exception& e) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (stop_) break;  // a statement interrupted by stop(): nothing to retry
      }
      const std::string why = e.what();
      // Refused: the database answers but will not take this server's records as they are
      // (its schema, the id, another store's records); retried, as an operator may fix it.
      const bool refused = dynamic_cast<const FailedPrecondition*>(&e) != nullptr;
      set_db(nullptr);
      // The lag first: a reader that sees the failure sees the records it holds back.
      try {
        note_lag(store_.forward_batch(cursor_, 1, false));
      } catch (const std::exception&) {
      }
      {
        std::lock_guard<std::mutex> lock(mu_);
        status_.connected = false;
        status_.state = refused ? "refused" : "unreachable";
        status_.last_error = why;
        ++status_.failures;
      }
      if (why != last_logged)
        log::error("forwarding_failed",
                   "forwarding to PostgreSQL failed (retrying in {:.1f} s; "
                   "records wait in the local store): {}",
                   backoff, why);
      last_logged = why;
      wait_s = backoff;
      backoff = std::min(opt_.retry_max_s, backoff * 2);
    }
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait_for(lock, std::chrono::duration<double>(wait_s), [&] { return stop_; });
  }
}

}  // namespace rangex
