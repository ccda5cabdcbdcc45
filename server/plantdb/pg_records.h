// Records read back from the plant-wide database into the store's own types, so that what
// the chain hashed can be recomputed from PostgreSQL's rows alone.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "store/stored_records.h"

namespace rangex {

class PgConnection;

// The fillets of `server_id` with these uids, each with its fragments in stored order.
std::map<int64_t, StoredFillet> pg_fillets(PgConnection& db, const std::string& server_id,
                                           const std::vector<int64_t>& uids);
// The audit entries of `server_id` with these local row ids.
std::map<int64_t, AuditEntry> pg_audit(PgConnection& db, const std::string& server_id,
                                       const std::vector<int64_t>& rows);

}  // namespace rangex
