// audit verify | audit export: the store's tamper-evident record (store/record_chain.h),
// read from the store's directory (rangexd may be running: the store is opened read-only).
#include <cstdio>
#include <fstream>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "plantdb/chain_check.h"
#include "plantdb/pg_connection.h"
#include "plantdb/plant_db_schema.h"
#include "store/store.h"

namespace rangex::cli {

namespace {
// Not core/json_text: a link's bytes are written as they are, never replaced, so that the
// export hashes as the chain did.
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += char(c);
    } else if (c == '\n') {
      out += "\\n";
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += char(c);
    }
  }
  return out + "\"";
}

// Every server's chain in the plant-wide database; the first broken link named per server.
int verify_plant_db(const std::string& conninfo) {
  PgConnection db(conninfo);
  require_plant_db_schema(db);
  const std::vector<ServerChainReport> rs = verify_plant_db_chains(db);
  if (rs.empty()) std::printf("no server has forwarded records to %s yet\n", db.where().c_str());
  bool ok = true;
  for (const ServerChainReport& r : rs) {
    if (r.ok) {
      std::printf("server %s: chain verified: %lld links from link %lld, head %s\n",
                  r.server_id.c_str(), (long long)r.links, (long long)r.first_seq, r.head.c_str());
    } else {
      ok = false;
      std::printf("server %s: chain BROKEN at link %lld after %lld good links: %s\n",
                  r.server_id.c_str(), (long long)r.first_broken_seq, (long long)r.links,
                  r.problem.c_str());
    }
  }
  return ok ? 0 : 1;
}

// --data, else the configuration's storage.
std::string store_dir(const Args& a) {
  if (a.has("data")) return a.get("data", "");
  return load_config(a.get("config", "")).storage;
}
}  // namespace

int cmd_audit(int argc, char** argv) {
  const std::string verb = argc > 2 ? argv[2] : "";
  if (verb == "verify") {
    const Args a(argc, argv, 3, {}, {"data", "config", "db"});
    a.expect_positionals(0, "audit verify [--data DIR | --config PLANT.yaml | --db CONNSTR]");
    if (a.has("db")) return verify_plant_db(no_password(a.get("db", ""), "--db"));
    const std::string dir = store_dir(a);
    const ChainReport r = Store::verify_chain(dir);
    if (!r.ok) {
      if (r.damaged)
        std::printf("store DAMAGED in %s: %s\n", dir.c_str(), r.problem.c_str());
      else
        std::printf("chain BROKEN in %s after %lld good links: %s\n", dir.c_str(),
                    (long long)r.links, r.problem.c_str());
      return 1;
    }
    std::printf("chain verified: %lld links (every fillet decision and audit entry), head %s\n",
                (long long)r.links, r.head.empty() ? "(empty)" : r.head.c_str());
    if (r.checkpoint_seq)
      std::printf(
          "  links 1-%lld were pruned by retention; verified from the checkpoint the "
          "latest retention.prune entry names\n",
          (long long)r.checkpoint_seq);
    return 0;
  }
  if (verb == "export") {
    const Args a(argc, argv, 3, {}, {"data", "config", "from-ns", "to-ns", "out"});
    a.expect_positionals(0,
                         "audit export [--data DIR | --config PLANT.yaml] [--from-ns T] "
                         "[--to-ns T] --out FILE.jsonl");
    if (!a.has("out")) fail("audit export needs --out FILE");
    const std::string dir = store_dir(a);
    const int64_t from = a.integer("from-ns", 0), to = a.integer("to-ns", 0);
    // The whole chain is verified first: an export of a broken chain proves nothing.
    const ChainReport r = Store::verify_chain(dir);
    if (!r.ok) fail("the chain of ", dir, " does not verify: ", r.problem);
    const std::vector<ChainLink> links = Store::chain_links(dir, from, to);
    std::ofstream out(a.get("out", ""));
    if (!out) fail(a.get("out", ""), ": cannot create");
    // Line 1: what this is and the hash the first link follows; then a line per link (its
    // row's canonical content, prev and hash: sha256(prev + "\n" + content) = hash); last:
    // the chain's head when exported, to be kept apart from the store.
    out << "{\"chain\":\"rangex-ledger-v1\",\"from_ns\":" << from << ",\"to_ns\":" << to
        << ",\"prev\":" << json_string(links.empty() ? r.head : links.front().prev)
        << ",\"hash\":\"sha256(prev + \\\"\\\\n\\\" + content)\"}\n";
    for (const ChainLink& l : links)
      out << "{\"seq\":" << l.seq << ",\"kind\":" << json_string(l.kind) << ",\"ref\":" << l.ref
          << ",\"ts_ns\":" << l.ts_ns << ",\"prev\":" << json_string(l.prev)
          << ",\"hash\":" << json_string(l.hash) << ",\"content\":" << json_string(l.content)
          << "}\n";
    out << "{\"head\":" << json_string(r.head) << ",\"links_in_store\":" << r.links << "}\n";
    if (!out.flush()) fail(a.get("out", ""), ": write failed");
    std::printf("exported %zu links to %s; chain head %s\n", links.size(), a.get("out", "").c_str(),
                r.head.c_str());
    return 0;
  }
  fail("audit needs a verb: verify or export (got '", verb, "')");
}

}  // namespace rangex::cli
