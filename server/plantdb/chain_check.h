// Every server's record chain verified in the plant-wide database: each link's hash
// recomputed from PostgreSQL's own rows (store/record_chain.h), so that a row changed
// behind rangex's back, a link removed or one inserted, names the first link that no longer
// holds, server by server.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace rangex {

class PgConnection;

struct ServerChainReport {
  std::string server_id;
  bool ok = true;
  int64_t links = 0;      // verified
  int64_t first_seq = 0;  // where the chain starts in the database (after a checkpoint)
  int64_t first_broken_seq = 0;
  std::string problem, head;
};

// `progress` (optional) is told each server's links as they are checked.
std::vector<ServerChainReport> verify_plant_db_chains(
    PgConnection& db, const std::function<void(const std::string&, int64_t)>& progress = {});

// One server's chain from its checkpoint up to link `up_to_seq` (before a prune drops it).
ServerChainReport verify_plant_db_chain(PgConnection& db, const std::string& server_id,
                                        int64_t up_to_seq);

}  // namespace rangex
