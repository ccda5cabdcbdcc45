// db migrate | db status: the plant-wide PostgreSQL's schema (applied here, never by a
// running rangexd) and where each server's forwarding stands.
#include <cstdio>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"

namespace rangex::cli {

int cmd_db(int argc, char** argv) {
  const std::string verb = argc > 2 ? argv[2] : "";
  if (verb == "migrate") {
    const Args a(argc, argv, 3, {}, {"db", "to"});
    a.expect_positionals(0, "db migrate --db CONNSTR [--to VERSION]");
    if (!a.has("db")) fail("db migrate needs --db CONNSTR (a libpq connection string)");
    PgConnection db(a.get("db", ""));
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
    PgConnection db(a.get("db", ""));
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
  fail("db needs a verb: migrate or status (got '", verb, "')");
}

}  // namespace rangex::cli
