#include "service/store.h"

#include <sqlite3.h>

#include <chrono>
#include <filesystem>

#include "core/error.h"

namespace fs = std::filesystem;

namespace rangex {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

namespace {
// A prepared statement that finalises itself.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &s_, nullptr) != SQLITE_OK)
      fail("store: cannot prepare '", sql, "': ", sqlite3_errmsg(db));
  }
  ~Stmt() { sqlite3_finalize(s_); }
  Stmt& bind(int i, int64_t v) {
    sqlite3_bind_int64(s_, i, v);
    return *this;
  }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(s_, i, v);
    return *this;
  }
  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.c_str(), int(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(s_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail("store: ", sqlite3_errmsg(db_));
  }
  int64_t i64(int c) const { return sqlite3_column_int64(s_, c); }
  double dbl(int c) const { return sqlite3_column_double(s_, c); }
  std::string str(int c) const {
    const auto* t = sqlite3_column_text(s_, c);
    return t ? reinterpret_cast<const char*>(t) : "";
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* s_ = nullptr;
};

StoredFillet fillet_row(const Stmt& q) {
  StoredFillet f;
  f.uid = q.i64(0);
  f.lane = int(q.i64(1));
  f.lane_fillet = q.i64(2);
  f.first_encoder = q.i64(3);
  f.rows = int(q.i64(4));
  f.decision = q.str(5);
  f.reason = q.str(6);
  f.beta0 = q.dbl(7);
  f.beta1 = q.dbl(8);
  f.resid_mean_dn = q.dbl(9);
  f.resid_std_dn = q.dbl(10);
  f.calibration_id = q.str(11);
  f.decided_ns = q.i64(12);
  f.belt_y0_mm = q.dbl(13);
  f.beta2 = q.dbl(14);
  return f;
}
constexpr const char* kFilletColumns =
    "uid, lane, lane_fillet, first_encoder, rows, decision, reason, beta0, beta1, "
    "resid_mean_dn, resid_std_dn, calibration_id, decided_ns, belt_y0_mm, beta2";
constexpr const char* kFragmentColumns =
    "kind, x_mm, y_mm, area_mm2, peak_z, attenuation_mm2, meat_mm, row0, row1, col0, col1";
StoredFragment fragment_row(const Stmt& g) {
  return {g.str(0), g.dbl(1),      g.dbl(2),      g.dbl(3),      g.dbl(4),      g.dbl(5),
          g.dbl(6), int(g.i64(7)), int(g.i64(8)), int(g.i64(9)), int(g.i64(10))};
}
}  // namespace

Store::Store(const std::string& dir) : dir_(dir) {
  fs::create_directories(fs::path(dir) / "images");
  const std::string path = (fs::path(dir) / "rangex.sqlite").string();
  if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    fail(path, ": cannot open the store: ", why);
  }
  // Another process holding the database (a backup, an audit query) is waited for briefly;
  // longer, and the write fails, the engine keeps the decision and retries.
  sqlite3_busy_timeout(db_, 250);
  exec("PRAGMA journal_mode=WAL");
  exec("PRAGMA synchronous=NORMAL");
  exec(
      "CREATE TABLE IF NOT EXISTS fillets (uid INTEGER PRIMARY KEY AUTOINCREMENT, lane INTEGER, "
      "lane_fillet INTEGER, first_encoder INTEGER, rows INTEGER, decision TEXT, reason TEXT, "
      "beta0 REAL, beta1 REAL, resid_mean_dn REAL, resid_std_dn REAL, calibration_id TEXT, "
      "decided_ns INTEGER, belt_y0_mm REAL, beta2 REAL DEFAULT 0)");
  exec("CREATE INDEX IF NOT EXISTS fillets_time ON fillets(decided_ns)");
  exec(
      "CREATE TABLE IF NOT EXISTS fragments (fillet_uid INTEGER, kind TEXT, x_mm REAL, "
      "y_mm REAL, area_mm2 REAL, peak_z REAL, attenuation_mm2 REAL, meat_mm REAL DEFAULT 0)");
  exec("CREATE INDEX IF NOT EXISTS fragments_fillet ON fragments(fillet_uid)");
  exec(
      "CREATE TABLE IF NOT EXISTS images (fillet_uid INTEGER, kind TEXT, path TEXT, "
      "PRIMARY KEY(fillet_uid, kind))");
  exec(
      "CREATE TABLE IF NOT EXISTS calibrations (lane INTEGER, id TEXT, yaml TEXT, "
      "uploaded_ns INTEGER, active INTEGER, PRIMARY KEY(lane, id))");
  // Stores made by earlier versions: add the columns they lack (their rows take the default).
  add_column("calibrations", "report", "TEXT DEFAULT ''");
  add_column("fillets", "beta2", "REAL DEFAULT 0");
  add_column("fragments", "meat_mm", "REAL DEFAULT 0");
  for (const char* c : {"row0", "row1", "col0", "col1"})
    add_column("fragments", c, "INTEGER DEFAULT 0");
  exec("CREATE TABLE IF NOT EXISTS audit (ts_ns INTEGER, who TEXT, what TEXT, detail TEXT)");
}

Store::~Store() {
  sqlite3_close(db_);
}

void Store::add_column(const std::string& table, const std::string& column,
                       const std::string& decl) {
  bool has = false;
  Stmt q(db_, ("PRAGMA table_info(" + table + ")").c_str());
  while (q.step()) has = has || q.str(1) == column;
  if (!has) exec("ALTER TABLE " + table + " ADD COLUMN " + column + " " + decl);
}

void Store::exec(const std::string& sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string why = err ? err : "?";
    sqlite3_free(err);
    fail("store: ", why, " (", sql, ")");
  }
}

int64_t Store::add_fillet(const StoredFillet& f) {
  std::lock_guard<std::mutex> lock(mu_);
  exec("BEGIN");
  try {
    Stmt q(db_,
           "INSERT INTO fillets (lane, lane_fillet, first_encoder, rows, decision, reason, beta0, "
           "beta1, resid_mean_dn, resid_std_dn, calibration_id, decided_ns, belt_y0_mm, beta2) "
           "VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
    q.bind(1, int64_t(f.lane))
        .bind(2, f.lane_fillet)
        .bind(3, f.first_encoder)
        .bind(4, int64_t(f.rows));
    q.bind(5, f.decision).bind(6, f.reason).bind(7, f.beta0).bind(8, f.beta1);
    q.bind(9, f.resid_mean_dn).bind(10, f.resid_std_dn).bind(11, f.calibration_id);
    q.bind(12, f.decided_ns).bind(13, f.belt_y0_mm).bind(14, f.beta2);
    q.step();
    const int64_t uid = sqlite3_last_insert_rowid(db_);
    for (const StoredFragment& g : f.fragments) {
      Stmt r(db_, (std::string("INSERT INTO fragments (fillet_uid, ") + kFragmentColumns +
                   ") VALUES (?,?,?,?,?,?,?,?,?,?,?,?)")
                      .c_str());
      r.bind(1, uid).bind(2, g.kind).bind(3, g.x_mm).bind(4, g.y_mm).bind(5, g.area_mm2);
      r.bind(6, g.peak_z).bind(7, g.attenuation_mm2).bind(8, g.meat_mm);
      r.bind(9, int64_t(g.row0)).bind(10, int64_t(g.row1)).bind(11, int64_t(g.col0));
      r.bind(12, int64_t(g.col1));
      r.step();
    }
    exec("COMMIT");
    return uid;
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
}

std::string Store::image_dir(int64_t uid) const {
  return (fs::path(dir_) / "images" / std::to_string(uid)).string();
}

void Store::add_image(int64_t uid, const std::string& kind, const std::string& path) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "INSERT OR REPLACE INTO images VALUES (?,?,?)");
  q.bind(1, uid).bind(2, kind).bind(3, path);
  q.step();
}

std::optional<std::string> Store::image_path(int64_t uid, const std::string& kind) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "SELECT path FROM images WHERE fillet_uid = ? AND kind = ?");
  q.bind(1, uid).bind(2, kind);
  if (!q.step()) return std::nullopt;
  return q.str(0);
}

std::optional<StoredFillet> Store::fillet(int64_t uid) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, (std::string("SELECT ") + kFilletColumns + " FROM fillets WHERE uid = ?").c_str());
  q.bind(1, uid);
  if (!q.step()) return std::nullopt;
  StoredFillet f = fillet_row(q);
  Stmt g(
      db_,
      (std::string("SELECT ") + kFragmentColumns + " FROM fragments WHERE fillet_uid = ?").c_str());
  g.bind(1, uid);
  while (g.step()) f.fragments.push_back(fragment_row(g));
  return f;
}

std::vector<StoredFillet> Store::list_fillets(int64_t from_ns, int64_t to_ns, int lane,
                                              int64_t after, int limit) {
  FilletQuery fq;
  fq.from_ns = from_ns, fq.to_ns = to_ns, fq.lane = lane, fq.after = after, fq.limit = limit;
  return list_fillets(fq);
}

std::vector<StoredFillet> Store::list_fillets(const FilletQuery& fq) {
  std::vector<StoredFillet> out;
  {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt q(db_, (std::string("SELECT ") + kFilletColumns +
                 " FROM fillets WHERE decided_ns >= ? AND (? = 0 OR decided_ns < ?) AND (? < 0 OR "
                 "lane = ?) AND uid > ? AND (? = '' OR decision = ?) ORDER BY uid " +
                 (fq.newest_first ? "DESC" : "ASC") + " LIMIT ?")
                    .c_str());
    q.bind(1, fq.from_ns).bind(2, fq.to_ns).bind(3, fq.to_ns);
    q.bind(4, int64_t(fq.lane)).bind(5, int64_t(fq.lane));
    q.bind(6, fq.newest_first ? int64_t(0) : fq.after)
        .bind(7, fq.decision)
        .bind(8, fq.decision)
        .bind(9, int64_t(fq.limit));
    while (q.step()) out.push_back(fillet_row(q));
  }
  for (StoredFillet& f : out) {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt g(db_, (std::string("SELECT ") + kFragmentColumns + " FROM fragments WHERE fillet_uid = ?")
                    .c_str());
    g.bind(1, f.uid);
    while (g.step()) f.fragments.push_back(fragment_row(g));
  }
  return out;
}

int64_t Store::count_fillets() {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "SELECT COUNT(*) FROM fillets");
  q.step();
  return q.i64(0);
}

void Store::add_calibration(const StoredCalibration& c) {
  std::lock_guard<std::mutex> lock(mu_);
  {
    Stmt e(db_, "SELECT 1 FROM calibrations WHERE lane = ? AND id = ?");
    e.bind(1, int64_t(c.lane)).bind(2, c.id);
    if (e.step())
      fail_exists("lane ", c.lane, " already has a calibration '", c.id,
                  "' (versions are immutable)");
  }
  Stmt q(db_,
         "INSERT INTO calibrations (lane, id, yaml, uploaded_ns, active, report) "
         "VALUES (?,?,?,?,?,?)");
  q.bind(1, int64_t(c.lane))
      .bind(2, c.id)
      .bind(3, c.yaml)
      .bind(4, c.uploaded_ns)
      .bind(5, int64_t(c.active))
      .bind(6, c.report);
  q.step();
}

std::vector<StoredCalibration> Store::calibrations(int lane) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_,
         "SELECT lane, id, yaml, uploaded_ns, active, report FROM calibrations "
         "WHERE (? < 0 OR lane = ?) ORDER BY lane, uploaded_ns");
  q.bind(1, int64_t(lane)).bind(2, int64_t(lane));
  std::vector<StoredCalibration> out;
  while (q.step())
    out.push_back({int(q.i64(0)), q.str(1), q.str(2), q.i64(3), q.i64(4) != 0, q.str(5)});
  return out;
}

std::optional<StoredCalibration> Store::calibration(int lane, const std::string& id) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_,
         "SELECT lane, id, yaml, uploaded_ns, active, report FROM calibrations "
         "WHERE lane = ? AND id = ?");
  q.bind(1, int64_t(lane)).bind(2, id);
  if (!q.step()) return std::nullopt;
  return StoredCalibration{int(q.i64(0)), q.str(1), q.str(2), q.i64(3), q.i64(4) != 0, q.str(5)};
}

void Store::set_active_calibration(int lane, const std::string& id) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt a(db_, "UPDATE calibrations SET active = (id = ?) WHERE lane = ?");
  a.bind(1, id).bind(2, int64_t(lane));
  a.step();
}

void Store::audit(const std::string& who, const std::string& what, const std::string& detail) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "INSERT INTO audit VALUES (?,?,?,?)");
  q.bind(1, now_ns())
      .bind(2, who.empty() ? std::string("unknown") : who)
      .bind(3, what)
      .bind(4, detail);
  q.step();
}

std::vector<AuditEntry> Store::audit_entries(int limit) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_,
         "SELECT ts_ns, who, what, detail FROM (SELECT rowid, * FROM audit ORDER BY rowid DESC "
         "LIMIT ?) ORDER BY rowid");
  q.bind(1, int64_t(limit));
  std::vector<AuditEntry> out;
  while (q.step()) out.push_back({q.i64(0), q.str(1), q.str(2), q.str(3)});
  return out;
}

std::vector<std::string> Store::audit_log(int limit) {
  std::vector<std::string> out;
  for (const AuditEntry& e : audit_entries(limit))
    out.push_back(std::to_string(e.ts_ns) + " " + e.who + " " + e.what + " " + e.detail);
  return out;
}

}  // namespace rangex
