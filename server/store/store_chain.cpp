// The store's record chain read back: audit entries appended as links, the chain's links
// of a time range with their contents (a chain proof), and its verification from the rows
// themselves on a read-only copy of the database.
#include <sqlite3.h>

#include <filesystem>
#include <set>

#include "core/error.h"
#include "store/record_chain.h"
#include "store/sqlite_stmt.h"
#include "store/store.h"

namespace fs = std::filesystem;

namespace rangex {

std::string Store::append_audit(const AuditEntry& e, const std::string& prev) {
  Stmt q(db_, "INSERT INTO audit VALUES (?,?,?,?)");
  q.bind(1, e.ts_ns).bind(2, e.who).bind(3, e.what).bind(4, e.detail);
  q.step();
  const int64_t row = sqlite3_last_insert_rowid(db_);
  return append_link("audit", row, e.ts_ns, chain_content(row, e), prev);
}

std::unique_ptr<Store> Store::read_only(const std::string& dir) {
  const std::string path = (fs::path(dir) / "rangex.sqlite").string();
  if (!fs::exists(path)) fail(path, ": no store here");
  std::unique_ptr<Store> view(new Store());
  if (sqlite3_open_v2(path.c_str(), &view->db_, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK)
    fail(path,
         ": cannot open the store: ", view->db_ ? sqlite3_errmsg(view->db_) : "out of memory");
  sqlite3_busy_timeout(view->db_, 2000);
  return view;
}

std::string Store::row_content(const std::string& kind, int64_t ref) {
  if (kind == "fillet") return chain_content(read_fillet(ref));
  if (kind == "audit") return chain_content(ref, read_audit(ref));
  fail("a link of unknown kind '", kind, "'");
}

AuditEntry Store::read_audit(int64_t row) {
  Stmt a(db_, "SELECT ts_ns, who, what, detail FROM audit WHERE rowid = ?");
  a.bind(1, row);
  if (!a.step()) fail_not_found("audit entry ", row, " is not in the store");
  return {a.i64(0), a.str(1), a.str(2), a.str(3)};
}

std::vector<ChainLink> Store::chain_links(const std::string& dir, int64_t from_ns, int64_t to_ns) {
  const std::unique_ptr<Store> view = read_only(dir);
  std::vector<ChainLink> out;
  Stmt q(view->db_,
         "SELECT seq, kind, ref, ts_ns, prev, hash FROM ledger WHERE ts_ns >= ? AND (? = 0 OR "
         "ts_ns < ?) ORDER BY seq");
  q.bind(1, from_ns).bind(2, to_ns).bind(3, to_ns);
  while (q.step()) {
    ChainLink l{q.i64(0), q.str(1), q.i64(2), q.i64(3), q.str(4), q.str(5), ""};
    l.content = view->row_content(l.kind, l.ref);
    out.push_back(std::move(l));
  }
  return out;
}

namespace {

void broken(ChainReport& r, int64_t seq, std::string why) {
  r.ok = false;
  r.first_broken_seq = seq;
  r.problem = std::move(why);
}

// Where the chain starts: the genesis, or the checkpoint retention left, which holds only
// when the chained entry of the pass that set it names it. False: the start was changed.
bool chain_start(sqlite3* db, ChainReport& r, std::string& prev) {
  prev = kChainGenesis;
  {
    Stmt t(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'chain_checkpoint'");
    if (!t.step()) return true;
  }
  Stmt c(db, "SELECT seq, hash FROM chain_checkpoint");
  if (!c.step()) return true;
  r.checkpoint_seq = c.i64(0);
  prev = r.head = c.str(1);
  Stmt a(db, "SELECT detail FROM audit WHERE what = 'retention.prune' ORDER BY rowid DESC LIMIT 1");
  if (!a.step() || a.str(0).find(prev) == std::string::npos) {
    broken(r, r.checkpoint_seq,
           "the chain's checkpoint (link " + std::to_string(r.checkpoint_seq) +
               ") is not the one the latest retention.prune audit entry names: the start of the "
               "chain was changed");
    return false;
  }
  return true;
}

// Rows that never joined the chain were added behind its back.
void rows_outside_chain(sqlite3* db, const std::set<int64_t>& fillets,
                        const std::set<int64_t>& audits, ChainReport& r) {
  Stmt f(db, "SELECT uid FROM fillets ORDER BY uid");
  while (r.ok && f.step())
    if (!fillets.count(f.i64(0)))
      broken(r, 0,
             "fillet " + std::to_string(f.i64(0)) + " is not in the chain (added afterwards)");
  Stmt a(db, "SELECT rowid FROM audit ORDER BY rowid");
  while (r.ok && a.step())
    if (!audits.count(a.i64(0)))
      broken(r, 0,
             "audit entry " + std::to_string(a.i64(0)) + " is not in the chain (added afterwards)");
}

}  // namespace

ChainReport Store::verify_chain(const std::string& dir) {
  const std::unique_ptr<Store> view = read_only(dir);
  sqlite3* db = view->db_;
  ChainReport r;
  // The whole database first: a chain that verifies over a corrupt images table is not a
  // record to trust.
  if (const std::string d = damage(db); !d.empty()) {
    r.ok = false;
    r.damaged = true;
    r.problem = "the database is damaged: " + d;
    return r;
  }
  std::string prev;
  if (!chain_start(db, r, prev)) return r;
  std::set<int64_t> fillets, audits;
  Stmt q(db, "SELECT seq, kind, ref, ts_ns, prev, hash FROM ledger ORDER BY seq");
  while (r.ok && q.step()) {
    const int64_t seq = q.i64(0), ref = q.i64(2);
    const std::string kind = q.str(1), link_prev = q.str(4), hash = q.str(5);
    const std::string what = kind + " " + std::to_string(ref);
    if (link_prev != prev) {
      broken(r, seq,
             "link " + std::to_string(seq) + " (" + what +
                 ") does not follow the link before it: a link was removed, inserted or "
                 "reordered");
      break;
    }
    std::string content;
    if (kind == "fillet") {
      if (!fillets.insert(ref).second) {
        broken(r, seq, "fillet " + std::to_string(ref) + " is chained twice");
        break;
      }
      try {
        content = chain_content(view->read_fillet(ref));
      } catch (const NotFound&) {
        broken(r, seq, "fillet " + std::to_string(ref) + " was removed from the store");
        break;
      }
    } else if (kind == "audit") {
      audits.insert(ref);
      Stmt a(db, "SELECT ts_ns, who, what, detail FROM audit WHERE rowid = ?");
      a.bind(1, ref);
      if (!a.step()) {
        broken(r, seq, "audit entry " + std::to_string(ref) + " was removed from the store");
        break;
      }
      content = chain_content(ref, {a.i64(0), a.str(1), a.str(2), a.str(3)});
    } else {
      broken(r, seq, "link " + std::to_string(seq) + " is of an unknown kind '" + kind + "'");
      break;
    }
    if (chain_hash(prev, content) != hash) {
      broken(r, seq,
             what + " was changed after it was recorded (its content no longer hashes to link " +
                 std::to_string(seq) + ")");
      break;
    }
    prev = hash;
    ++r.links;
    r.head = hash;
  }
  if (r.ok) rows_outside_chain(db, fillets, audits, r);
  return r;
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

std::vector<AuditEntry> Store::audit_entries_of(const std::string& prefix, int limit) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_,
         "SELECT ts_ns, who, what, detail FROM (SELECT rowid, * FROM audit WHERE "
         "substr(what, 1, length(?)) = ? ORDER BY rowid DESC LIMIT ?) ORDER BY rowid");
  q.bind(1, prefix);
  q.bind(2, prefix);
  q.bind(3, int64_t(limit));
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
