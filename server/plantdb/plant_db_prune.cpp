#include "plantdb/plant_db_prune.h"

#include <algorithm>

#include "core/error.h"
#include "plantdb/chain_check.h"
#include "plantdb/pg_array.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"

namespace rangex {

namespace {
const char* const kTables[] = {"ledger", "fillets", "fragments", "images", "audit"};

// The earliest day, before `d`, that the chains need kept: a dropped link with a kept link
// before it in its chain, or a dropped record that a kept link names. "" when none.
std::string needed_before(PgConnection& db, const std::string& d) {
  const PgRows r = db.exec(
      "SELECT least("
      // Links stamped before the cutoff that come after a kept link of their server.
      "(SELECT min(o.day) FROM ledger o WHERE o.day < $1::date AND o.seq > (SELECT min(n.seq) "
      "FROM ledger n WHERE n.server_id = o.server_id AND n.day >= $1::date)), "
      // Fillets and audit entries before the cutoff whose link is kept.
      "(SELECT min(f.day) FROM fillets f WHERE f.day < $1::date AND NOT EXISTS (SELECT 1 FROM "
      "ledger l WHERE l.day < $1::date AND l.server_id = f.server_id AND l.kind = 'fillet' AND "
      "l.ref = f.uid)), "
      "(SELECT min(a.day) FROM audit a WHERE a.day < $1::date AND NOT EXISTS (SELECT 1 FROM "
      "ledger l WHERE l.day < $1::date AND l.server_id = a.server_id AND l.kind = 'audit' AND "
      "l.ref = a.row_id)), "
      // Images and fragments go with their fillet's day; one kept past it holds it.
      "(SELECT min(i.day) FROM images i WHERE i.day < $1::date AND NOT EXISTS (SELECT 1 FROM "
      "fillets f WHERE f.day < $1::date AND f.server_id = i.server_id AND f.uid = "
      "i.fillet_uid)))::text",
      {d});
  return r.str(0, 0);
}
}  // namespace

PlantDbPruneReport plant_db_prune(PgConnection& db, const std::string& before_day, bool dry_run,
                                  const std::string& who) {
  require_plant_db_schema(db);
  PlantDbPruneReport rep;
  rep.asked_before = before_day;
  rep.dry_run = dry_run;
  db.exec("SET statement_timeout = 0");
  db.exec("BEGIN");
  try {
    // One prune at a time, and no day partition made while it runs.
    db.exec("SELECT pg_advisory_xact_lock(hashtext('rangex db prune'))");
    db.exec("SELECT pg_advisory_xact_lock(hashtext('rangex_day_partitions'))");
    std::string d = db.exec("SELECT $1::date::text", {before_day}).str(0, 0);
    for (;;) {
      const std::string need = needed_before(db, d);
      if (need.empty() || need >= d) break;
      d = need;
    }
    rep.before = d;
    // Each server's last dropped link: its chain then starts after it. The dropped links
    // verify first, from the server's present checkpoint.
    const PgRows last = db.exec(
        "SELECT DISTINCT ON (server_id) server_id, seq, hash FROM ledger WHERE day < $1::date "
        "ORDER BY server_id, seq DESC",
        {d});
    for (int i = 0; i < last.rows(); ++i) {
      PlantDbCheckpoint c{last.str(i, 0), last.i64(i, 1), last.str(i, 2)};
      const ServerChainReport v = verify_plant_db_chain(db, c.server_id, c.seq);
      if (!v.ok)
        throw FailedPrecondition(join(
            "db prune: server ", c.server_id, "'s chain is broken at link ", v.first_broken_seq,
            " (", v.problem, "): a broken chain is evidence and is not pruned"));
      rep.checkpoints.push_back(std::move(c));
    }
    const PgRows counts = db.exec(
        "SELECT (SELECT count(*) FROM fillets WHERE day < $1::date), (SELECT count(*) FROM "
        "ledger WHERE day < $1::date)",
        {d});
    rep.fillets = counts.i64(0, 0), rep.links = counts.i64(0, 1);
    PgArray tables;
    for (const char* t : kTables) tables.add(std::string(t));
    const PgRows parts = db.exec(
        "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid JOIN pg_class "
        "p ON p.oid = i.inhparent WHERE p.relname = ANY($1::text[]) AND "
        "to_date(right(c.relname, 8), 'YYYYMMDD') < $2::date ORDER BY c.relname",
        {tables.text(), d});
    for (int i = 0; i < parts.rows(); ++i) rep.partitions.push_back(parts.str(i, 0));
    if (dry_run) {
      db.exec("ROLLBACK");
      return rep;
    }
    for (const PlantDbCheckpoint& c : rep.checkpoints)
      db.exec(
          "INSERT INTO chain_checkpoints VALUES ($1, $2, $3, $4::date) ON CONFLICT (server_id) "
          "DO UPDATE SET seq = excluded.seq, hash = excluded.hash, before_day = "
          "excluded.before_day",
          {c.server_id, std::to_string(c.seq), c.hash, d});
    for (const std::string& p : rep.partitions)
      db.exec("DROP TABLE " + p);  // names from pg_class, of the form table_YYYYMMDD
    std::string detail;
    for (const PlantDbCheckpoint& c : rep.checkpoints)
      detail += (detail.empty() ? "" : "; ") + c.server_id + " from link " +
                std::to_string(c.seq + 1) + " after " + c.hash;
    db.exec(
        "INSERT INTO prunes VALUES ((extract(epoch from clock_timestamp()) * 1e9)::bigint, $1, "
        "$2::date, $3, $4, $5, $6)",
        {who, d, std::to_string(rep.partitions.size()), std::to_string(rep.fillets),
         std::to_string(rep.links), detail});
    db.exec("COMMIT");
  } catch (...) {
    db.rollback_quietly();
    throw;
  }
  return rep;
}

}  // namespace rangex
