// The store's side of forwarding to the plant-wide database: records after a cursor, and
// the cursor the database holds, kept so that retention never prunes what it lacks.
#include <sqlite3.h>

#include "core/error.h"
#include "store/sqlite_stmt.h"
#include "store/store.h"

namespace rangex {

ForwardBatch Store::forward_batch(const ForwardCursor& after, int limit, bool with_active) {
  if (limit < 1) fail("forward_batch: limit must be >= 1");
  ForwardBatch b;
  b.next = after;
  std::lock_guard<std::mutex> lock(mu_);
  // One read transaction: the links, their rows and the images are one snapshot.
  exec("BEGIN");
  try {
    {
      Stmt q(db_,
             "SELECT seq, kind, ref, ts_ns, prev, hash FROM ledger WHERE seq > ? ORDER BY seq "
             "LIMIT ?");
      q.bind(1, after.seq).bind(2, int64_t(limit));
      while (q.step())
        b.links.push_back({q.i64(0), q.str(1), q.i64(2), q.i64(3), q.str(4), q.str(5)});
    }
    for (const ForwardLink& l : b.links) {
      if (l.kind == "fillet") {
        b.fillets.push_back(read_fillet(l.ref));
      } else if (l.kind == "audit") {
        b.audit.push_back({l.ref, read_audit(l.ref)});
      } else {
        fail("store: link ", l.seq, " is of unknown kind '", l.kind, "'");
      }
      b.next.seq = l.seq;
    }
    {
      // An image whose fillet the database does not hold yet waits for it: the fillet's
      // link comes first.
      // A fillet's uid grows with its link's seq (both are taken in one transaction).
      int64_t last_uid = 0;
      Stmt u(db_,
             "SELECT ref FROM ledger WHERE kind = 'fillet' AND seq <= ? ORDER BY seq DESC "
             "LIMIT 1");
      u.bind(1, b.next.seq);
      if (u.step()) last_uid = u.i64(0);
      Stmt q(db_,
             "SELECT l.seq, l.fillet_uid, l.kind, coalesce(i.path, ''), f.decided_ns FROM "
             "image_log l JOIN fillets f ON f.uid = l.fillet_uid LEFT JOIN images i ON "
             "i.fillet_uid = l.fillet_uid AND i.kind = l.kind WHERE l.seq > ? AND l.fillet_uid "
             "<= ? ORDER BY l.seq LIMIT ?");
      q.bind(1, after.image_seq).bind(2, last_uid).bind(3, int64_t(limit));
      while (q.step()) {
        b.images.push_back({q.i64(0), q.i64(1), q.i64(4), q.str(2), q.str(3)});
        b.next.image_seq = q.i64(0);
      }
    }
    for (const bool learned : {false, true}) {
      Stmt q(db_, (std::string("SELECT rowid, lane, id, yaml, report, uploaded_ns FROM ") +
                   (learned ? "learned_settings" : "calibrations") +
                   " WHERE rowid > ? ORDER BY rowid LIMIT ?")
                      .c_str());
      q.bind(1, learned ? after.learned_row : after.calibration_row).bind(2, int64_t(limit));
      while (q.step()) {
        b.settings.push_back(
            {learned, q.i64(0), int(q.i64(1)), q.str(2), q.str(3), q.str(4), q.i64(5)});
        (learned ? b.next.learned_row : b.next.calibration_row) = q.i64(0);
      }
    }
    if (with_active)
      for (const bool learned : {false, true}) {
        Stmt q(db_, (std::string("SELECT lane, id FROM ") +
                     (learned ? "learned_settings" : "calibrations") + " WHERE active != 0")
                        .c_str());
        while (q.step()) b.active.push_back({learned, int(q.i64(0)), q.str(1)});
      }
    {
      Stmt q(db_, "SELECT count(*) FROM ledger WHERE seq > ?");
      q.bind(1, after.seq);
      if (q.step()) b.pending = q.i64(0);
      b.head_seq = head_seq_locked();
      Stmt o(db_, "SELECT ts_ns FROM ledger WHERE seq > ? ORDER BY seq LIMIT 1");
      o.bind(1, after.seq);
      if (o.step()) b.oldest_ns = o.i64(0);
    }
    exec("COMMIT");
  } catch (...) {
    rollback();
    throw;
  }
  return b;
}

int64_t Store::head_seq() {
  std::lock_guard<std::mutex> lock(mu_);
  return head_seq_locked();
}

int64_t Store::head_seq_locked() {
  Stmt h(db_, "SELECT coalesce(max(seq), 0) FROM ledger");
  h.step();
  return h.i64(0);
}

std::optional<std::string> Store::link_hash(int64_t seq) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "SELECT hash FROM ledger WHERE seq = ?");
  q.bind(1, seq);
  if (!q.step()) return std::nullopt;
  return q.str(0);
}

void Store::set_forwarded(const ForwardCursor& c) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, "INSERT OR REPLACE INTO forward_state VALUES (1, ?, ?, ?, ?)");
  q.bind(1, c.seq).bind(2, c.image_seq).bind(3, c.calibration_row).bind(4, c.learned_row);
  q.step();
}

ForwardCursor Store::forwarded() {
  std::lock_guard<std::mutex> lock(mu_);
  return forwarded_locked();
}

ForwardCursor Store::forwarded_locked() {
  Stmt q(db_, "SELECT seq, image_seq, calibration_row, learned_row FROM forward_state");
  ForwardCursor c;
  if (q.step()) c = {q.i64(0), q.i64(1), q.i64(2), q.i64(3)};
  return c;
}

}  // namespace rangex
