// Retention in the plant-wide database (rangexctl db prune): whole days dropped as
// partitions, keeping the chain's checkpoint rule. What is dropped is, for every server, a
// prefix of its chain with the records those links name: the cutoff moves earlier until no
// kept link is older than a dropped one and no kept link names a dropped record (a clock
// stepped back, a fillet decided just before midnight and chained just after). The dropped
// links are verified first (a broken chain is evidence, never pruned), each server's chain
// then starts after its last dropped link (chain_checkpoints), and the drop is logged
// (prunes). docs/plant-wide.md.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

class PgConnection;

struct PlantDbCheckpoint {
  std::string server_id;
  int64_t seq = 0;
  std::string hash;
};

struct PlantDbPruneReport {
  std::string asked_before, before;     // days "YYYY-MM-DD": asked for, and as the chains allow
  std::vector<std::string> partitions;  // dropped (or, dry run, that would be)
  std::vector<PlantDbCheckpoint> checkpoints;
  int64_t fillets = 0, links = 0;
  bool dry_run = false;
};

// Drops every day before `before_day` ("YYYY-MM-DD") that the chains allow, in one
// transaction under the schema's lock. Throws FailedPrecondition naming the server and link
// when a dropped link does not verify.
PlantDbPruneReport plant_db_prune(PgConnection& db, const std::string& before_day, bool dry_run,
                                  const std::string& who);

}  // namespace rangex
