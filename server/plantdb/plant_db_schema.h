// The plant-wide PostgreSQL schema, owned by rangex: versioned migrations applied by
// `rangexctl db migrate`, never by a running rangexd (a server finds a schema older than it
// needs and says so). docs/plant-wide.md.
#pragma once
#include <functional>
#include <string>
#include <vector>

namespace rangex {

class PgConnection;

struct Migration {
  int version;
  const char* description;
  const char* sql;
};

// Every migration, oldest first; the last one's version is what this build needs.
const std::vector<Migration>& plant_db_migrations();
int plant_db_schema_version_needed();

// The schema version the database holds (0: none of rangex's tables).
int plant_db_schema_version(PgConnection& db);

// Applies the migrations the database lacks, up to `target` (0: all), each in its own
// transaction, under an advisory lock so that two `db migrate` runs do not interleave.
// Reports each applied migration; returns how many were applied.
int plant_db_migrate(PgConnection& db, int target = 0,
                     const std::function<void(const Migration&)>& applied = {});

// Throws Error unless the database holds the schema this build needs, naming both versions
// and the command that migrates it.
void require_plant_db_schema(PgConnection& db);

}  // namespace rangex
