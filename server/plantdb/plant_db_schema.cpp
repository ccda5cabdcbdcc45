#include "plantdb/plant_db_schema.h"

#include "core/error.h"
#include "plantdb/pg_connection.h"

namespace rangex {

namespace {
// Version 1: every server's records. Record tables are partitioned by the UTC day of their
// time (retention drops whole days: rangexctl db prune), keyed by the server and its own
// local key, so that a resent batch changes nothing.
constexpr const char* kRecords = R"SQL(
CREATE TABLE servers (
  server_id text PRIMARY KEY,
  host text NOT NULL DEFAULT '',
  http text NOT NULL DEFAULT '',
  started_ns bigint NOT NULL DEFAULT 0,
  seen_ns bigint NOT NULL DEFAULT 0,
  head_seq bigint NOT NULL DEFAULT 0,
  forwarded_seq bigint NOT NULL DEFAULT 0,
  image_seq bigint NOT NULL DEFAULT 0,
  calibration_row bigint NOT NULL DEFAULT 0,
  learned_row bigint NOT NULL DEFAULT 0,
  lag_records bigint NOT NULL DEFAULT 0,
  lag_seconds double precision NOT NULL DEFAULT 0,
  serving boolean NOT NULL DEFAULT true,
  health text NOT NULL DEFAULT ''
);
CREATE TABLE ledger (
  server_id text NOT NULL, seq bigint NOT NULL, kind text NOT NULL, ref bigint NOT NULL,
  ts_ns bigint NOT NULL, prev text NOT NULL, hash text NOT NULL, day date NOT NULL,
  PRIMARY KEY (server_id, seq, day)
) PARTITION BY RANGE (day);
CREATE TABLE fillets (
  server_id text NOT NULL, uid bigint NOT NULL, lane integer NOT NULL,
  lane_fillet bigint NOT NULL, first_encoder bigint NOT NULL, rows integer NOT NULL,
  decision text NOT NULL, reason text NOT NULL, calibration_id text NOT NULL,
  beta0 double precision, beta1 double precision, beta2 double precision,
  resid_mean_dn double precision, resid_std_dn double precision, belt_y0_mm double precision,
  decided_ns bigint NOT NULL, day date NOT NULL,
  PRIMARY KEY (server_id, uid, day)
) PARTITION BY RANGE (day);
CREATE TABLE fragments (
  server_id text NOT NULL, fillet_uid bigint NOT NULL, idx integer NOT NULL, kind text NOT NULL,
  x_mm double precision, y_mm double precision, area_mm2 double precision,
  peak_z double precision, attenuation_mm2 double precision, meat_mm double precision,
  row0 integer, row1 integer, col0 integer, col1 integer, bone_mg double precision,
  day date NOT NULL,
  PRIMARY KEY (server_id, fillet_uid, idx, day)
) PARTITION BY RANGE (day);
CREATE TABLE images (
  server_id text NOT NULL, fillet_uid bigint NOT NULL, kind text NOT NULL, path text NOT NULL,
  day date NOT NULL,
  PRIMARY KEY (server_id, fillet_uid, kind, day)
) PARTITION BY RANGE (day);
CREATE TABLE audit (
  server_id text NOT NULL, row_id bigint NOT NULL, ts_ns bigint NOT NULL, who text NOT NULL,
  what text NOT NULL, detail text NOT NULL, day date NOT NULL,
  PRIMARY KEY (server_id, row_id, day)
) PARTITION BY RANGE (day);
-- Where a server's chain starts in PostgreSQL once whole days were dropped (db prune).
CREATE TABLE chain_checkpoints (
  server_id text PRIMARY KEY, seq bigint NOT NULL, hash text NOT NULL, before_day date NOT NULL
);
-- A day's partitions of every record table, made when a server first forwards a record of
-- that day (a routine step, not a migration), serialised between servers.
CREATE FUNCTION rangex_day_partitions(d date) RETURNS void LANGUAGE plpgsql AS $$
DECLARE
  t text;
  n text;
BEGIN
  PERFORM pg_advisory_xact_lock(hashtext('rangex_day_partitions'));
  FOREACH t IN ARRAY ARRAY['ledger', 'fillets', 'fragments', 'images', 'audit'] LOOP
    n := t || '_' || to_char(d, 'YYYYMMDD');
    IF to_regclass(n) IS NULL THEN
      EXECUTE format('CREATE TABLE %I PARTITION OF %I FOR VALUES FROM (%L) TO (%L)',
                     n, t, d, d + 1);
    END IF;
  END LOOP;
END $$;
)SQL";

// Version 2: lane settings' history (calibrations, learned settings) and the dashboard's
// searches (by time, by lane and time, rejects by time).
constexpr const char* kSettingsAndSearch = R"SQL(
CREATE TABLE settings (
  server_id text NOT NULL, kind text NOT NULL CHECK (kind IN ('calibration', 'learned')),
  lane integer NOT NULL, id text NOT NULL, yaml text NOT NULL, report text NOT NULL,
  uploaded_ns bigint NOT NULL, active boolean NOT NULL DEFAULT false,
  PRIMARY KEY (server_id, kind, lane, id)
);
CREATE INDEX fillets_time ON fillets (decided_ns);
CREATE INDEX fillets_lane_time ON fillets (server_id, lane, decided_ns);
CREATE INDEX fillets_decision_time ON fillets (decision, decided_ns);
CREATE INDEX audit_time ON audit (ts_ns);
)SQL";

// Version 3: what retention dropped, when, and where each server's chain then started; a
// lane's history across servers.
constexpr const char* kPrunes = R"SQL(
CREATE TABLE prunes (
  pruned_ns bigint NOT NULL, who text NOT NULL, before_day date NOT NULL,
  partitions integer NOT NULL, fillets bigint NOT NULL, links bigint NOT NULL,
  detail text NOT NULL
);
-- A lane's latest record, whichever server ran it (a lane moved between servers).
CREATE INDEX fillets_plant_lane_time ON fillets (lane, decided_ns);
)SQL";

constexpr long long kMigrationLock = 0x72616e676578;  // "rangex"
}  // namespace

const std::vector<Migration>& plant_db_migrations() {
  static const std::vector<Migration> m = {
      {1, "every server's records: ledger, fillets, fragments, images, audit by day", kRecords},
      {2, "lane settings' history; indexes for the dashboard's searches", kSettingsAndSearch},
      {3, "the log of retention's partition drops (db prune); lanes across servers", kPrunes},
  };
  return m;
}

int plant_db_schema_version_needed() {
  return plant_db_migrations().back().version;
}

int plant_db_schema_version(PgConnection& db) {
  if (db.exec("SELECT to_regclass('rangex_schema') IS NOT NULL").str(0, 0) != "t") return 0;
  return int(db.exec("SELECT coalesce(max(version), 0) FROM rangex_schema").i64(0, 0));
}

int plant_db_migrate(PgConnection& db, int target,
                     const std::function<void(const Migration&)>& applied) {
  const int want = target > 0 ? target : plant_db_schema_version_needed();
  if (want > plant_db_schema_version_needed())
    fail("db migrate: version ", want, " is unknown to this build (it knows up to ",
         plant_db_schema_version_needed(), ")");
  // An index built over a year of records may take longer than a forwarder's statements.
  db.exec("SET statement_timeout = 0");
  db.exec("SELECT pg_advisory_lock(" + std::to_string(kMigrationLock) + ")");
  int done = 0;
  try {
    db.exec(
        "CREATE TABLE IF NOT EXISTS rangex_schema (version integer PRIMARY KEY, description "
        "text NOT NULL, applied_ns bigint NOT NULL)");
    const int have = plant_db_schema_version(db);
    if (have > plant_db_schema_version_needed())
      fail("db migrate: the database holds schema version ", have, ", newer than this build's ",
           plant_db_schema_version_needed(), ": use a newer rangexctl");
    for (const Migration& m : plant_db_migrations()) {
      if (m.version <= have || m.version > want) continue;
      db.exec("BEGIN");
      try {
        db.exec(m.sql);
        db.exec(
            "INSERT INTO rangex_schema VALUES ($1, $2, (extract(epoch from clock_timestamp()) * "
            "1e9)::bigint)",
            {std::to_string(m.version), std::string(m.description)});
        db.exec("COMMIT");
      } catch (...) {
        db.rollback_quietly();
        throw;
      }
      ++done;
      if (applied) applied(m);
    }
  } catch (...) {
    if (db.ok()) db.exec("SELECT pg_advisory_unlock(" + std::to_string(kMigrationLock) + ")");
    throw;
  }
  db.exec("SELECT pg_advisory_unlock(" + std::to_string(kMigrationLock) + ")");
  return done;
}

void require_plant_db_schema(PgConnection& db) {
  const int have = plant_db_schema_version(db), need = plant_db_schema_version_needed();
  if (have == need) return;
  if (have < need)
    throw FailedPrecondition(join(
        "PostgreSQL at ", db.where(), " holds rangex schema version ", have, "; this build needs ",
        need, ": run `rangexctl db migrate --db CONNSTR` (a running server never migrates)"));
  throw FailedPrecondition(join("PostgreSQL at ", db.where(), " holds rangex schema version ", have,
                                ", newer than this build's ", need, ": upgrade rangexd"));
}

}  // namespace rangex
