#include "store/store.h"

#include <sqlite3.h>

#include <chrono>
#include <filesystem>
#include <vector>

#include "core/error.h"
#include "store/directory_lock.h"
#include "store/record_chain.h"
#include "store/sqlite_stmt.h"

namespace fs = std::filesystem;

namespace rangex {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

namespace {
// Where a decision's images wait until the decision is stored (staging_dir).
fs::path staging_root(const std::string& dir) {
  return fs::path(dir) / "images" / "staged";
}

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
    "kind, x_mm, y_mm, area_mm2, peak_z, attenuation_mm2, meat_mm, row0, row1, col0, col1, "
    "bone_mg";
StoredFragment fragment_row(const Stmt& g) {
  return {g.str(0), g.dbl(1),      g.dbl(2),      g.dbl(3),      g.dbl(4),       g.dbl(5),
          g.dbl(6), int(g.i64(7)), int(g.i64(8)), int(g.i64(9)), int(g.i64(10)), g.dbl(11)};
}
}  // namespace

std::string Store::damage(sqlite3* db) {
  // Table by table (PRAGMA quick_check(TABLE), SQLite 3.33 and later, covers the table and
  // its indexes), so that what is refused is named: a malformed page in the fragments or
  // images table once let rangexd start SERVING and fail only on reads.
  std::vector<std::string> tables;
  try {
    Stmt t(db, "SELECT name FROM sqlite_master WHERE type = 'table'");
    while (t.step()) tables.push_back(t.str(0));
  } catch (const std::exception& e) {
    return std::string("its schema cannot be read: ") + e.what();
  }
  std::string out;
  for (const std::string& name : tables) {
    std::string first;
    try {
      Stmt q(db, ("PRAGMA quick_check(\"" + name + "\")").c_str());
      while (q.step() && first.empty())
        if (q.str(0) != "ok") first = q.str(0);
    } catch (const std::exception& e) {
      first = e.what();
    }
    if (!first.empty()) out += (out.empty() ? "table " : "; table ") + name + ": " + first;
  }
  return out;
}

Store::Store(const std::string& dir) : dir_(dir), lock_(std::make_unique<DirectoryLock>(dir)) {
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
  // Checked before anything is written: a damaged store is refused at start, not found out
  // by the first read of a plant's records.
  if (const std::string d = damage(db_); !d.empty()) {
    sqlite3_close(db_);
    db_ = nullptr;
    fail(path, ": the store is damaged (", d,
         "); rangexd will not run on it: restore it from a backup, or move it aside to start "
         "a new one");
  }
  // Images staged for decisions the last process did not store (it stopped, crashed or was
  // made to exit mid-write, which can leave a .part): those fillets are decided again from
  // the lines the feeders resend, and staged anew. Nothing else reads them.
  std::error_code ec;
  fs::remove_all(staging_root(dir), ec);
  exec("PRAGMA journal_mode=WAL");
  // The durability rule: a decision is committed (to the WAL, fsync'd) before it is
  // published, so a decision any subscriber saw survives a crash of rangexd or of the
  // machine. One fsync per decision and audit entry: a few per second at a plant's rate.
  exec("PRAGMA synchronous=FULL");
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
  exec(
      "CREATE TABLE IF NOT EXISTS learned_settings (lane INTEGER, id TEXT, yaml TEXT, "
      "uploaded_ns INTEGER, active INTEGER, report TEXT DEFAULT '', PRIMARY KEY(lane, id))");
  // Stores made by earlier versions: add the columns they lack (their rows take the default).
  add_column("calibrations", "report", "TEXT DEFAULT ''");
  add_column("fillets", "beta2", "REAL DEFAULT 0");
  add_column("fragments", "meat_mm", "REAL DEFAULT 0");
  add_column("fragments", "bone_mg", "REAL DEFAULT 0");
  for (const char* c : {"row0", "row1", "col0", "col1"})
    add_column("fragments", c, "INTEGER DEFAULT 0");
  exec("CREATE TABLE IF NOT EXISTS audit (ts_ns INTEGER, who TEXT, what TEXT, detail TEXT)");
  // Every image reference in the order it was stored, under a key never reused (the images
  // table's rowids are, once its last rows are pruned): what the forwarder follows. A store
  // made before it has its images logged once, in their order.
  bool had_log = false;
  {
    Stmt t(db_, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'image_log'");
    had_log = t.step();
  }
  exec(
      "CREATE TABLE IF NOT EXISTS image_log (seq INTEGER PRIMARY KEY AUTOINCREMENT, fillet_uid "
      "INTEGER, kind TEXT)");
  if (!had_log)
    exec(
        "INSERT INTO image_log (fillet_uid, kind) SELECT fillet_uid, kind FROM images ORDER BY "
        "rowid");
  // What the plant-wide database holds of this store (one row; store_forward.cpp).
  exec(
      "CREATE TABLE IF NOT EXISTS forward_state (id INTEGER PRIMARY KEY CHECK (id = 1), seq "
      "INTEGER, image_seq INTEGER, calibration_row INTEGER, learned_row INTEGER)");
  // The hash chain over fillets and audit entries (store/record_chain.h).
  exec(
      "CREATE TABLE IF NOT EXISTS ledger (seq INTEGER PRIMARY KEY AUTOINCREMENT, kind TEXT, "
      "ref INTEGER, ts_ns INTEGER, prev TEXT, hash TEXT)");
  exec("CREATE INDEX IF NOT EXISTS ledger_time ON ledger(ts_ns)");
  exec(
      "CREATE TABLE IF NOT EXISTS lane_progress (lane INTEGER PRIMARY KEY, durable_encoder "
      "INTEGER, updated_ns INTEGER)");
  // Where the chain starts once retention has pruned its oldest links (one row).
  exec(
      "CREATE TABLE IF NOT EXISTS chain_checkpoint (id INTEGER PRIMARY KEY CHECK (id = 1), "
      "seq INTEGER, hash TEXT, ts_ns INTEGER, before_ns INTEGER)");
  std::lock_guard<std::mutex> lock(mu_);
  head_ = kChainGenesis;
  {
    Stmt c(db_, "SELECT hash FROM chain_checkpoint");
    if (c.step()) head_ = c.str(0);
    Stmt q(db_, "SELECT hash FROM ledger ORDER BY seq DESC LIMIT 1");
    if (q.step()) head_ = q.str(0);
  }
  if (head_ == kChainGenesis) chain_existing();
}

void Store::chain_existing() {
  // A store from before the chain: its rows are chained once, fillets then audit entries,
  // each in the order stored.
  exec("BEGIN");
  try {
    std::vector<int64_t> uids;
    {
      Stmt q(db_, "SELECT uid FROM fillets ORDER BY uid");
      while (q.step()) uids.push_back(q.i64(0));
    }
    std::string head = head_;
    for (int64_t uid : uids) {
      const StoredFillet f = read_fillet(uid);
      head = append_link("fillet", uid, f.decided_ns, chain_content(f), head);
    }
    std::vector<std::pair<int64_t, AuditEntry>> rows;
    {
      Stmt q(db_, "SELECT rowid, ts_ns, who, what, detail FROM audit ORDER BY rowid");
      while (q.step()) rows.push_back({q.i64(0), {q.i64(1), q.str(2), q.str(3), q.str(4)}});
    }
    for (const auto& [row, e] : rows)
      head = append_link("audit", row, e.ts_ns, chain_content(row, e), head);
    exec("COMMIT");
    head_ = head;
  } catch (...) {
    rollback();
    throw;
  }
}

std::string Store::append_link(const char* kind, int64_t ref, int64_t ts_ns,
                               const std::string& content, const std::string& prev) {
  const std::string hash = chain_hash(prev, content);
  Stmt q(db_, "INSERT INTO ledger (kind, ref, ts_ns, prev, hash) VALUES (?,?,?,?,?)");
  q.bind(1, std::string(kind)).bind(2, ref).bind(3, ts_ns).bind(4, prev).bind(5, hash);
  q.step();
  return hash;
}

StoredFillet Store::read_fillet(int64_t uid) {
  Stmt q(db_, (std::string("SELECT ") + kFilletColumns + " FROM fillets WHERE uid = ?").c_str());
  q.bind(1, uid);
  if (!q.step()) fail_not_found("fillet ", uid, " is not in the store");
  StoredFillet f = fillet_row(q);
  Stmt g(db_, (std::string("SELECT ") + kFragmentColumns +
               " FROM fragments WHERE fillet_uid = ? ORDER BY rowid")
                  .c_str());
  g.bind(1, uid);
  while (g.step()) f.fragments.push_back(fragment_row(g));
  return f;
}

Store::Store() = default;  // here, where DirectoryLock is whole

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
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    std::string why = err ? err : "?";
    sqlite3_free(err);
    if ((rc & 0xff) == SQLITE_FULL) why = "disk full: " + why;
    fail("store: ", why, " (", sql, ")");
  }
}

void Store::rollback() noexcept {
  // SQLite rolls a transaction back by itself on some errors (a full disk among them); a
  // ROLLBACK then would fail and its "no transaction is active" hide the error that counts.
  if (!sqlite3_get_autocommit(db_)) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
}

void Store::cap_pages_for_tests(int64_t pages) {
  std::lock_guard<std::mutex> lock(mu_);
  exec("PRAGMA max_page_count = " + std::to_string(pages));
}

int64_t Store::add_fillet(const StoredFillet& f, const std::string& staged_images) {
  std::lock_guard<std::mutex> lock(mu_);
  exec("BEGIN");
  std::string moved_to;  // image_dir(uid) once the staged images are there
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
                   ") VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?)")
                      .c_str());
      r.bind(1, uid).bind(2, g.kind).bind(3, g.x_mm).bind(4, g.y_mm).bind(5, g.area_mm2);
      r.bind(6, g.peak_z).bind(7, g.attenuation_mm2).bind(8, g.meat_mm);
      r.bind(9, int64_t(g.row0)).bind(10, int64_t(g.row1)).bind(11, int64_t(g.col0));
      r.bind(12, int64_t(g.col1)).bind(13, g.bone_mg);
      r.step();
    }
    if (!staged_images.empty()) {
      // A folder left at this uid by a transaction that did not commit is not this fillet's.
      const fs::path to = image_dir(uid);
      fs::remove_all(to);
      fs::rename(staged_images, to);
      moved_to = to.string();
      for (const auto& e : fs::directory_iterator(to))
        if (e.path().extension() == ".png")
          register_image(uid, e.path().stem().string(), e.path().string());
    }
    // The decision joins the chain in the same transaction: stored means chained.
    StoredFillet chained = f;
    chained.uid = uid;
    const std::string head =
        append_link("fillet", uid, f.decided_ns, chain_content(chained), head_);
    exec("COMMIT");
    head_ = head;
    return uid;
  } catch (...) {
    rollback();
    if (!moved_to.empty()) {
      std::error_code ec;  // the staged images stay for the retry
      fs::rename(moved_to, staged_images, ec);
    }
    throw;
  }
}

void Store::register_image(int64_t uid, const std::string& kind, const std::string& path) {
  Stmt q(db_, "INSERT OR REPLACE INTO images VALUES (?,?,?)");
  q.bind(1, uid).bind(2, kind).bind(3, path);
  q.step();
  Stmt l(db_, "INSERT INTO image_log (fillet_uid, kind) VALUES (?,?)");
  l.bind(1, uid).bind(2, kind);
  l.step();
}

std::string Store::staging_dir(const StoredFillet& f) const {
  return (staging_root(dir_) / (std::to_string(f.lane) + "-" + std::to_string(f.first_encoder)))
      .string();
}

std::string Store::image_dir(int64_t uid) const {
  return (fs::path(dir_) / "images" / std::to_string(uid)).string();
}

void Store::add_image(int64_t uid, const std::string& kind, const std::string& path) {
  std::lock_guard<std::mutex> lock(mu_);
  exec("BEGIN");
  try {
    register_image(uid, kind, path);
    exec("COMMIT");
  } catch (...) {
    rollback();
    throw;
  }
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

void Store::audit(const std::string& who, const std::string& what, const std::string& detail) {
  std::lock_guard<std::mutex> lock(mu_);
  const AuditEntry e{now_ns(), who.empty() ? std::string("unknown") : who, what, detail};
  exec("BEGIN");
  try {
    const std::string head = append_audit(e, head_);
    exec("COMMIT");
    head_ = head;
  } catch (...) {
    rollback();
    throw;
  }
}

void Store::save_progress(const std::vector<std::pair<int, int64_t>>& lane_durable) {
  std::lock_guard<std::mutex> lock(mu_);
  exec("BEGIN");
  try {
    for (const auto& [lane, durable] : lane_durable) {
      Stmt q(db_,
             "INSERT OR REPLACE INTO lane_progress (lane, durable_encoder, updated_ns) VALUES "
             "(?,?,?)");
      q.bind(1, int64_t(lane)).bind(2, durable).bind(3, now_ns());
      q.step();
    }
    exec("COMMIT");
  } catch (...) {
    rollback();
    throw;
  }
}

std::vector<std::pair<int, int64_t>> Store::progress() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::pair<int, int64_t>> out;
  Stmt q(db_, "SELECT lane, durable_encoder FROM lane_progress ORDER BY lane");
  while (q.step()) out.push_back({int(q.i64(0)), q.i64(1)});
  return out;
}

int64_t Store::next_lane_fillet(int lane) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "SELECT COALESCE(MAX(lane_fillet) + 1, 0) FROM fillets WHERE lane = ?");
  q.bind(1, int64_t(lane));
  return q.step() ? q.i64(0) : 0;
}

std::optional<int64_t> Store::last_fillet_end(int lane) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_,
         "SELECT first_encoder + rows - 1 FROM fillets WHERE lane = ? ORDER BY uid DESC LIMIT 1");
  q.bind(1, int64_t(lane));
  if (!q.step()) return std::nullopt;
  return q.i64(0);
}

}  // namespace rangex
