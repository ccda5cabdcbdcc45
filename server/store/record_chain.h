// The tamper-evident record (HACCP, 9 CFR 417.5): every fillet decision and every audit
// entry is appended, in the order they are stored, to one hash chain. A link holds the
// SHA-256 of the previous link's hash and of its row's canonical content, so a row changed,
// removed or inserted afterwards, or links reordered, no longer verify. The content is
// recomputed from the rows themselves when the chain is verified, never taken from a copy.
#pragma once
#include <string>

#include "store/stored_records.h"

namespace rangex {

// The hash before the first link.
inline constexpr const char* kChainGenesis =
    "0000000000000000000000000000000000000000000000000000000000000000";

// Canonical text of a stored fillet (its uid, every field, its fragments in stored order)
// and of an audit entry (its row id and fields). Doubles are written exactly (%.17g), so
// the text read back from the store is the text that was hashed.
std::string chain_content(const StoredFillet& f);
std::string chain_content(int64_t audit_row, const AuditEntry& e);

// Lower-case hex SHA-256 of prev + "\n" + content.
std::string chain_hash(const std::string& prev, const std::string& content);

}  // namespace rangex
