// The tamper-evident record: every decision and audit entry in one hash chain; a row
// changed, removed or added behind the store's back, or a link removed, is named by
// verification; a store from before the chain is chained when first opened.
#include <gtest/gtest.h>
#include <openssl/sha.h>
#include <sqlite3.h>

#include <cstdio>

#include "store/record_chain.h"
#include "store/store.h"
#include "store_tamper.h"
#include "temp_dir.h"

using namespace rangex;

namespace {
using test::tamper;
StoredFillet fillet(int lane, int64_t encoder, const char* decision, int fragments) {
  StoredFillet f;
  f.lane = lane;
  f.lane_fillet = encoder / 100;
  f.first_encoder = encoder;
  f.rows = 250;
  f.decision = decision;
  f.reason = fragments ? "bone, \"calcified\"\nsecond line" : "";
  f.beta0 = 8.25, f.beta1 = -0.0312345678901234, f.beta2 = 1.0 / 3.0;
  f.calibration_id = "cal-1";
  f.decided_ns = 1000 + encoder;
  for (int k = 0; k < fragments; ++k)
    f.fragments.push_back({"bone", 1.0 + k, 2.0, 3.5, -12.0, 0.8, 3.7, 1, 2, 3, 4});
  return f;
}

// Five links: fillets 1..3 and two audit entries between them.
void fill(Store& s) {
  s.add_fillet(fillet(0, 100, "pass", 0));
  s.audit("alice", "calibration.activate", "lane 0 cal-1");
  s.add_fillet(fillet(1, 200, "reject", 2));
  s.add_fillet(fillet(0, 300, "not_inspected", 0));
  s.audit("bob", "thresholds", "lane 1 z=4");
}

// The independent reference: OpenSSL's one-shot SHA256, hex.
std::string sha256_hex(const std::string& s) {
  unsigned char md[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(s.data()), s.size(), md);
  std::string out;
  char buf[3];
  for (unsigned char c : md) {
    std::snprintf(buf, sizeof buf, "%02x", c);
    out += buf;
  }
  return out;
}
}  // namespace

TEST(RecordChain, HashIsSha256OfPrevNewlineContent) {
  EXPECT_EQ(chain_hash("", ""), sha256_hex("\n"));
  // The FIPS 180-2 vector for "abc", through the same formula.
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(chain_hash(kChainGenesis, "x"), sha256_hex(std::string(kChainGenesis) + "\nx"));
}

TEST(RecordChain, AnUntouchedStoreVerifiesAndTheChainGoesOnAfterAReopen) {
  test::TempDir t;
  std::string head;
  {
    Store s(t.str());
    fill(s);
    head = s.chain_head();
  }
  ChainReport r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.links, 5);
  EXPECT_EQ(r.head, head);
  {
    Store s(t.str());
    EXPECT_EQ(s.chain_head(), head);
    s.add_fillet(fillet(2, 400, "reject", 1));
  }
  r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.links, 6);
  // The export's links check by hashing alone, each following the one before.
  const std::vector<ChainLink> links = Store::chain_links(t.str(), 0, 0);
  ASSERT_EQ(links.size(), 6u);
  std::string prev = kChainGenesis;
  for (const ChainLink& l : links) {
    EXPECT_EQ(l.prev, prev);
    EXPECT_EQ(sha256_hex(l.prev + "\n" + l.content), l.hash);
    prev = l.hash;
  }
  EXPECT_EQ(prev, r.head);
  // A time range: the links stamped inside it only.
  EXPECT_EQ(Store::chain_links(t.str(), 1150, 1350).size(), 2u);  // fillets at 1200, 1300
}

TEST(RecordChain, EveryKindOfTamperingIsNamed) {
  struct Case {
    const char* sql;
    const char* says;
    int64_t seq;  // the first broken link (0: a row outside the chain)
  };
  const Case cases[] = {
      {"UPDATE fillets SET decision = 'pass' WHERE uid = 2", "fillet 2 was changed", 3},
      {"UPDATE fragments SET x_mm = 9 WHERE rowid = 1", "fillet 2 was changed", 3},
      {"DELETE FROM fragments WHERE rowid = 2", "fillet 2 was changed", 3},
      {"UPDATE audit SET who = 'mallory' WHERE rowid = 1", "audit 1 was changed", 2},
      {"DELETE FROM fillets WHERE uid = 3", "fillet 3 was removed", 4},
      {"DELETE FROM audit WHERE rowid = 2", "audit entry 2 was removed", 5},
      {"DELETE FROM ledger WHERE seq = 2", "does not follow", 3},
      {"INSERT INTO fillets (lane, decision, decided_ns) VALUES (0, 'pass', 5)",
       "fillet 4 is not in the chain", 0},
      {"INSERT INTO audit VALUES (7, 'x', 'y', 'z')", "audit entry 3 is not in the chain", 0},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.sql);
    test::TempDir t;
    {
      Store s(t.str());
      fill(s);
    }
    ASSERT_TRUE(Store::verify_chain(t.str()).ok);
    tamper(t, c.sql);
    const ChainReport r = Store::verify_chain(t.str());
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.problem.find(c.says), std::string::npos) << r.problem;
    EXPECT_EQ(r.first_broken_seq, c.seq) << r.problem;
  }
}

TEST(RecordChain, AStoreFromBeforeTheChainIsChainedWhenOpened) {
  test::TempDir t;
  {
    Store s(t.str());
    fill(s);
  }
  tamper(t, "DROP TABLE ledger");
  {
    Store s(t.str());  // chains the five rows it finds
    s.add_fillet(fillet(3, 500, "pass", 0));
  }
  const ChainReport r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.links, 6);
}
