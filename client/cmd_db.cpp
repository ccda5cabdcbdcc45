// db migrate | db status | db prune: the plant-wide PostgreSQL's schema (applied here, never
// by a running rangexd), where each server's forwarding stands, and retention by whole days.
#include <cstdio>
#include <cstdlib>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "plantdb/forwarder.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_prune.h"
#include "plantdb/plant_db_schema.h"
#include "store/store.h"

namespace rangex::cli {

int cmd_db(int argc, char** argv) {
  const std::string verb = argc > 2 ? argv[2] : "";
  if (verb == "migrate") {
    const Args a(argc, argv, 3, {}, {"db", "to"});
    a.expect_positionals(0, "db migrate --db CONNSTR [--to VERSION]");
    if (!a.has("db")) fail("db migrate needs --db CONNSTR (a libpq connection string)");
    PgConnection db(no_password(a.get("db", ""), "--db"));
    const int before = plant_db_schema_version(db);
    const int n = plant_db_migrate(db, int(a.integer("to", 0)), [](const Migration& m) {
      std::printf("applied migration %d: %s\n", m.version, m.description);
    });
    std::printf("%s: rangex schema version %d%s\n", db.where().c_str(), plant_db_schema_version(db),
                n ? (" (was " + std::to_string(before) + ")").c_str() : ", nothing to do");
    return 0;
  }
  if (verb == "status") {
    const Args a(argc, argv, 3, {}, {"db"});
    a.expect_positionals(0, "db status --db CONNSTR");
    if (!a.has("db")) fail("db status needs --db CONNSTR (a libpq connection string)");
    PgConnection db(no_password(a.get("db", ""), "--db"));
    const int have = plant_db_schema_version(db), need = plant_db_schema_version_needed();
    std::printf("%s: rangex schema version %d (this build needs %d)\n", db.where().c_str(), have,
                need);
    if (have == 0) return have == need ? 0 : 1;
    const PgRows s = db.exec(
        "SELECT server_id, host, forwarded_seq, head_seq, lag_records, (extract(epoch from "
        "clock_timestamp()) * 1e9)::bigint - seen_ns FROM servers ORDER BY server_id");
    for (int i = 0; i < s.rows(); ++i)
      std::printf(
          "  server %s (host %s): %lld links forwarded, %lld behind, last seen %.0f s ago\n",
          s.str(i, 0).c_str(), s.str(i, 1).c_str(), s.i64(i, 2), s.i64(i, 4),
          double(s.i64(i, 5)) / 1e9);
    return have == need ? 0 : 1;
  }
  if (verb == "prune") {
    const Args a(argc, argv, 3, {"dry-run"}, {"db", "keep-days", "before"});
    a.expect_positionals(0,
                         "db prune --db CONNSTR --keep-days N | --before YYYY-MM-DD [--dry-run]");
    if (!a.has("db")) fail("db prune needs --db CONNSTR (a libpq connection string)");
    if (a.has("keep-days") == a.has("before"))
      fail(
          "db prune needs one of --keep-days N (whole UTC days kept before today) or --before "
          "YYYY-MM-DD");
    std::string before = a.get("before", "");
    if (a.has("keep-days")) {
      const int64_t keep = a.integer("keep-days", 0);
      if (keep < 1) fail("db prune: --keep-days must be >= 1 (today is never dropped)");
      before = utc_day(now_ns() - keep * 86'400'000'000'000);
    } else if (before.size() != 10 || before[4] != '-' || before[7] != '-') {
      fail("db prune: --before '", before, "' must be a day as YYYY-MM-DD");
    }
    PgConnection db(no_password(a.get("db", ""), "--db"));
    const char* user = std::getenv("USER");
    const PlantDbPruneReport r = plant_db_prune(db, before, a.flag("dry-run"),
                                                std::string("rangexctl:") + (user ? user : "?"));
    if (r.before != r.asked_before)
      std::printf(
          "the chains keep %s onwards (asked: before %s): a kept link needs the days from it\n",
          r.before.c_str(), r.asked_before.c_str());
    std::printf("%s %zu partitions of days before %s: %lld fillets, %lld links\n",
                r.dry_run ? "would drop" : "dropped", r.partitions.size(), r.before.c_str(),
                (long long)r.fillets, (long long)r.links);
    for (const PlantDbCheckpoint& c : r.checkpoints)
      std::printf("  server %s: chain %s from link %lld (after %s)\n", c.server_id.c_str(),
                  r.dry_run ? "would start" : "starts", (long long)(c.seq + 1), c.hash.c_str());
    return 0;
  }
  fail("db needs a verb: migrate, status or prune (got '", verb, "')");
}

}  // namespace rangex::cli
