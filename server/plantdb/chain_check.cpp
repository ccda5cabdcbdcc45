#include "plantdb/chain_check.h"

#include "plantdb/pg_connection.h"
#include "plantdb/pg_records.h"
#include "store/record_chain.h"

namespace rangex {

namespace {
constexpr int kPage = 5000;

ServerChainReport verify_server(PgConnection& db, const std::string& id, int64_t up_to_seq,
                                const std::function<void(const std::string&, int64_t)>& progress) {
  ServerChainReport r;
  r.server_id = id;
  std::string prev = kChainGenesis;
  int64_t expect = 1;
  const PgRows cp = db.exec("SELECT seq, hash FROM chain_checkpoints WHERE server_id = $1", {id});
  if (cp.rows()) expect = cp.i64(0, 0) + 1, prev = cp.str(0, 1);
  r.first_seq = expect;
  auto broken = [&](int64_t seq, const std::string& why) {
    r.ok = false;
    r.first_broken_seq = seq;
    r.problem = why;
  };
  for (;;) {
    const PgRows l = db.exec(
        "SELECT seq, kind, ref, prev, hash FROM ledger WHERE server_id = $1 AND seq >= $2 AND "
        "seq <= $3 ORDER BY seq LIMIT " +
            std::to_string(kPage),
        {id, std::to_string(expect), std::to_string(up_to_seq)});
    if (l.rows() == 0) break;
    std::vector<int64_t> fillets, audit;
    for (int i = 0; i < l.rows(); ++i)
      (l.str(i, 1) == "fillet" ? fillets : audit).push_back(l.i64(i, 2));
    const auto f = pg_fillets(db, id, fillets);
    const auto a = pg_audit(db, id, audit);
    for (int i = 0; i < l.rows(); ++i) {
      const int64_t seq = l.i64(i, 0), ref = l.i64(i, 2);
      const std::string kind = l.str(i, 1);
      if (seq != expect) {
        broken(expect, "link " + std::to_string(expect) + " is missing");
        return r;
      }
      if (l.str(i, 3) != prev) {
        broken(seq, "its prev does not name the link before it");
        return r;
      }
      std::string content;
      if (kind == "fillet") {
        auto it = f.find(ref);
        if (it == f.end()) {
          broken(seq, "fillet " + std::to_string(ref) + " is missing");
          return r;
        }
        content = chain_content(it->second);
      } else if (kind == "audit") {
        auto it = a.find(ref);
        if (it == a.end()) {
          broken(seq, "audit entry " + std::to_string(ref) + " is missing");
          return r;
        }
        content = chain_content(ref, it->second);
      } else {
        broken(seq, "a link of unknown kind '" + kind + "'");
        return r;
      }
      if (chain_hash(prev, content) != l.str(i, 4)) {
        broken(seq, "the " + kind + " " + std::to_string(ref) +
                        " it chains was changed after it was stored");
        return r;
      }
      prev = l.str(i, 4);
      ++expect;
      ++r.links;
    }
    if (progress) progress(id, r.links);
  }
  r.head = prev;
  if (up_to_seq != INT64_MAX) return r;
  // Records no link names (inserted behind rangex's back) break the chain too.
  const PgRows extra = db.exec(
      "SELECT (SELECT count(*) FROM fillets WHERE server_id = $1) - (SELECT count(*) FROM ledger "
      "WHERE server_id = $1 AND kind = 'fillet'), (SELECT count(*) FROM audit WHERE server_id = "
      "$1) - (SELECT count(*) FROM ledger WHERE server_id = $1 AND kind = 'audit')",
      {id});
  if (cp.rows() == 0 && (extra.i64(0, 0) != 0 || extra.i64(0, 1) != 0))
    broken(0, std::to_string(extra.i64(0, 0)) + " fillets and " + std::to_string(extra.i64(0, 1)) +
                  " audit entries outside the chain");
  return r;
}
}  // namespace

std::vector<ServerChainReport> verify_plant_db_chains(
    PgConnection& db, const std::function<void(const std::string&, int64_t)>& progress) {
  std::vector<ServerChainReport> out;
  const PgRows s = db.exec(
      "SELECT server_id FROM servers UNION SELECT DISTINCT server_id FROM ledger ORDER BY 1");
  for (int i = 0; i < s.rows(); ++i)
    out.push_back(verify_server(db, s.str(i, 0), INT64_MAX, progress));
  return out;
}

ServerChainReport verify_plant_db_chain(PgConnection& db, const std::string& server_id,
                                        int64_t up_to_seq) {
  return verify_server(db, server_id, up_to_seq, {});
}

}  // namespace rangex
