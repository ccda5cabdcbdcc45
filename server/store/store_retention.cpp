// Retention (Store::prune): images first, then the chain's oldest records as a prefix, with
// a checkpoint where the chain now starts and a chained audit entry naming it.
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "store/record_chain.h"
#include "store/sqlite_stmt.h"
#include "store/store.h"

namespace fs = std::filesystem;

namespace rangex {

int64_t Store::prune_images(int64_t before_ns, int max_rows, std::vector<std::string>& files) {
  // Passed fillets' images go first, then not inspected, then rejected (the record that
  // matters most keeps its pictures longest).
  std::vector<std::pair<int64_t, std::string>> rows;
  {
    Stmt q(db_,
           "SELECT i.fillet_uid, i.kind, i.path FROM images i JOIN fillets f ON f.uid = "
           "i.fillet_uid WHERE f.decided_ns < ? ORDER BY CASE f.decision WHEN 'pass' THEN 0 "
           "WHEN 'reject' THEN 2 ELSE 1 END, f.decided_ns LIMIT ?");
    q.bind(1, before_ns).bind(2, int64_t(max_rows));
    while (q.step()) {
      rows.push_back({q.i64(0), q.str(1)});
      files.push_back(q.str(2));
    }
  }
  for (const auto& [uid, kind] : rows) {
    Stmt d(db_, "DELETE FROM images WHERE fillet_uid = ? AND kind = ?");
    d.bind(1, uid).bind(2, kind);
    d.step();
  }
  return int64_t(rows.size());
}

namespace {

struct Link {
  int64_t seq;
  std::string kind;
  int64_t ref;
  std::string hash;
};

// While forwarding is on, nothing the plant-wide database lacks is pruned: the cutoffs stop
// at the first record it does not hold (a link, or an image of a fillet).
void stop_at_unforwarded(sqlite3* db, const ForwardCursor& done, int64_t& records_before_ns,
                         int64_t& images_before_ns) {
  Stmt l(db, "SELECT ts_ns FROM ledger WHERE seq > ? ORDER BY seq LIMIT 1");
  l.bind(1, done.seq);
  if (l.step()) records_before_ns = std::min(records_before_ns, l.i64(0));
  Stmt i(db,
         "SELECT f.decided_ns FROM image_log l JOIN fillets f ON f.uid = l.fillet_uid "
         "WHERE l.seq > ? ORDER BY l.seq LIMIT 1");
  i.bind(1, done.image_seq);
  if (i.step()) {
    records_before_ns = std::min(records_before_ns, i.i64(0));
    images_before_ns = std::min(images_before_ns, i.i64(0));
  }
}

// The prefix of the chain stamped before the cutoff: it ends at the first link inside
// retention, whatever older links follow that one. At most max_rows links.
std::vector<Link> prunable_links(sqlite3* db, int64_t records_before_ns, int max_rows) {
  int64_t stop = INT64_MAX;
  {
    Stmt q(db, "SELECT MIN(seq) FROM ledger WHERE ts_ns >= ?");
    q.bind(1, records_before_ns);
    if (q.step() && !q.null(0)) stop = q.i64(0);
  }
  std::vector<Link> links;
  Stmt q(db, "SELECT seq, kind, ref, hash FROM ledger WHERE seq < ? ORDER BY seq LIMIT ?");
  q.bind(1, stop).bind(2, int64_t(max_rows));
  while (q.step()) links.push_back({q.i64(0), q.str(1), q.i64(2), q.str(3)});
  return links;
}

// Each link's row: a fillet with its fragments, images (their files listed for removal) and
// image log, or an audit entry.
void delete_linked_rows(sqlite3* db, const std::vector<Link>& links, PruneReport& rep,
                        std::vector<std::string>& files) {
  for (const Link& l : links) {
    if (l.kind == "fillet") {
      Stmt p(db, "SELECT path FROM images WHERE fillet_uid = ?");
      p.bind(1, l.ref);
      while (p.step()) files.push_back(p.str(0));
      for (const char* sql :
           {"DELETE FROM images WHERE fillet_uid = ?", "DELETE FROM image_log WHERE fillet_uid = ?",
            "DELETE FROM fragments WHERE fillet_uid = ?", "DELETE FROM fillets WHERE uid = ?"}) {
        Stmt d(db, sql);
        d.bind(1, l.ref);
        d.step();
      }
      ++rep.fillets;
    } else {
      Stmt d(db, "DELETE FROM audit WHERE rowid = ?");
      d.bind(1, l.ref);
      d.step();
      ++rep.audit_entries;
    }
  }
}

// The links up to the last pruned one go; the chain now starts from its hash.
void set_checkpoint(sqlite3* db, const PruneReport& rep, int64_t records_before_ns) {
  Stmt d(db, "DELETE FROM ledger WHERE seq <= ?");
  d.bind(1, rep.checkpoint_seq);
  d.step();
  Stmt c(db,
         "INSERT OR REPLACE INTO chain_checkpoint (id, seq, hash, ts_ns, before_ns) "
         "VALUES (1, ?, ?, ?, ?)");
  c.bind(1, rep.checkpoint_seq).bind(2, rep.checkpoint_hash).bind(3, now_ns());
  c.bind(4, records_before_ns);
  c.step();
}

}  // namespace

PruneReport Store::prune(int64_t records_before_ns, int64_t images_before_ns, int max_rows) {
  if (max_rows < 1) fail("prune: max_rows must be >= 1");
  PruneReport rep;
  std::vector<std::string> files;  // removed once the transaction holds
  {
    std::lock_guard<std::mutex> lock(mu_);
    exec("BEGIN");
    try {
      if (hold_unforwarded_)
        stop_at_unforwarded(db_, forwarded_locked(), records_before_ns, images_before_ns);
      rep.images = prune_images(std::max(images_before_ns, records_before_ns), max_rows, files);
      rep.more = rep.images == max_rows;
      const std::vector<Link> links = prunable_links(db_, records_before_ns, max_rows);
      rep.more = rep.more || int(links.size()) == max_rows;
      delete_linked_rows(db_, links, rep, files);
      rep.links = int64_t(links.size());
      std::string head = head_;
      if (!links.empty()) {
        rep.checkpoint_seq = links.back().seq;
        rep.checkpoint_hash = links.back().hash;
        set_checkpoint(db_, rep, records_before_ns);
        head = append_audit({now_ns(), "rangexd", "retention.prune",
                             join(rep.links, " links (", rep.fillets, " fillets, ",
                                  rep.audit_entries, " audit entries) stamped before ",
                                  records_before_ns, " ns pruned; the chain now starts after link ",
                                  rep.checkpoint_seq, " ", rep.checkpoint_hash)},
                            head);
      }
      if (rep.images)
        head = append_audit({now_ns(), "rangexd", "retention.images",
                             join(rep.images, " images of fillets decided before ",
                                  std::max(images_before_ns, records_before_ns), " ns removed")},
                            head);
      exec("COMMIT");
      head_ = head;
    } catch (...) {
      rollback();
      throw;
    }
  }
  for (const std::string& f : files) {
    std::error_code ec;
    fs::remove(f, ec);
    fs::remove(fs::path(f).parent_path(), ec);  // the fillet's folder, once empty
  }
  return rep;
}

}  // namespace rangex
