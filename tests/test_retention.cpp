// Retention: images go first (passed, then not inspected, then rejected), records go as the
// chain's oldest prefix and never inside retention, the chain verifies from the checkpoint
// the pass leaves (and names a checkpoint changed or removed), and the chain goes on after.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>

#include "store/store.h"
#include "store_tamper.h"
#include "temp_dir.h"

using namespace rangex;
namespace fs = std::filesystem;

namespace {
using test::tamper;

constexpr int64_t kDay = 86400LL * 1000000000LL;

// A decided fillet with one stored image file (the store keeps images of any decision).
int64_t decided(Store& s, const char* decision, int64_t at_ns, bool image = true) {
  StoredFillet f;
  f.lane = 1;
  f.decision = decision;
  f.reason = std::string(decision) + " for the test";
  f.decided_ns = at_ns;
  f.calibration_id = "cal";
  if (std::string(decision) == "reject") f.fragments.push_back({"bone", 1, 2, 3, 9, 1, 4});
  const int64_t uid = s.add_fillet(f);
  if (image) {
    fs::create_directories(s.image_dir(uid));
    const std::string path = s.image_dir(uid) + "/overlay.png";
    std::ofstream(path) << "png";
    s.add_image(uid, "overlay", path);
  }
  return uid;
}

}  // namespace

TEST(Retention, ThePrefixBeforeTheCutoffGoesAndNothingInsideRetention) {
  test::TempDir t;
  const int64_t now = now_ns(), cutoff = now - 730 * kDay;
  int64_t old_pass, old_reject, new_reject, late_old;
  {
    Store s(t.str());
    old_pass = decided(s, "pass", cutoff - 3 * kDay);
    old_reject = decided(s, "reject", cutoff - 2 * kDay);
    s.audit("cert:engineer-1", "calibration.activate", "lane 1 cal");  // stamped now
    new_reject = decided(s, "reject", cutoff + kDay);
    // Older than the cutoff but stored after a link inside retention: the prefix stops
    // before it (a chain can only be cut at its start).
    late_old = decided(s, "not_inspected", cutoff - kDay);
    const std::string old_image = *s.image_path(old_reject, "overlay");

    const PruneReport p = s.prune(cutoff, cutoff);
    EXPECT_EQ(p.links, 2);
    EXPECT_EQ(p.fillets, 2);
    EXPECT_EQ(p.audit_entries, 0);
    EXPECT_FALSE(p.more);
    EXPECT_EQ(p.checkpoint_seq, 2);
    EXPECT_FALSE(s.fillet(old_pass));
    EXPECT_FALSE(s.fillet(old_reject));
    EXPECT_FALSE(fs::exists(old_image));
    // Inside retention: the reject's record, fragments and image stay.
    const auto kept = s.fillet(new_reject);
    ASSERT_TRUE(kept);
    EXPECT_EQ(kept->fragments.size(), 1u);
    ASSERT_TRUE(s.image_path(new_reject, "overlay"));
    EXPECT_TRUE(fs::exists(*s.image_path(new_reject, "overlay")));
    EXPECT_TRUE(s.fillet(late_old));  // behind a link inside retention
    // A second pass finds nothing more before the next link inside retention.
    EXPECT_EQ(s.prune(cutoff, cutoff).links, 0);
  }
  ChainReport r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.checkpoint_seq, 2);
  {
    Store s(t.str());  // the chain goes on after a reopen, from its pruned state
    decided(s, "pass", now);
    bool audited = false;
    for (const AuditEntry& e : s.audit_entries(10))
      audited |= e.what == "retention.prune" &&
                 e.detail.find("the chain now starts after link 2") != std::string::npos;
    EXPECT_TRUE(audited);
  }
  r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.links, 6);  // audit, new reject, late old, prune entry, image entry, new pass
}

TEST(Retention, ImagesGoFirstPassedThenNotInspectedThenRejected) {
  test::TempDir t;
  Store s(t.str());
  const int64_t now = now_ns();
  const int64_t reject = decided(s, "reject", now - 30 * kDay);  // the oldest
  const int64_t missing = decided(s, "not_inspected", now - 20 * kDay);
  const int64_t pass = decided(s, "pass", now - 10 * kDay);
  // Images older than a week, records kept: one image per pass.
  auto next = [&] { return s.prune(0, now - 7 * kDay, 1); };
  EXPECT_EQ(next().images, 1);
  EXPECT_FALSE(s.image_path(pass, "overlay"));
  EXPECT_TRUE(s.image_path(missing, "overlay"));
  EXPECT_TRUE(s.image_path(reject, "overlay"));
  EXPECT_EQ(next().images, 1);
  EXPECT_FALSE(s.image_path(missing, "overlay"));
  EXPECT_TRUE(s.image_path(reject, "overlay"));
  EXPECT_EQ(next().images, 1);
  EXPECT_FALSE(s.image_path(reject, "overlay"));
  EXPECT_EQ(next().images, 0);
  for (int64_t uid : {reject, missing, pass}) EXPECT_TRUE(s.fillet(uid)) << uid;  // records stay
  const ChainReport r = Store::verify_chain(t.str());
  EXPECT_TRUE(r.ok) << r.problem;
  EXPECT_EQ(r.checkpoint_seq, 0);
}

TEST(Retention, ACheckpointChangedOrRemovedIsNamed) {
  const int64_t now = now_ns();
  auto pruned_store = [&](const test::TempDir& t) {
    Store s(t.str());
    for (int k = 0; k < 5; ++k) decided(s, k % 2 ? "reject" : "pass", now - (40 - k) * kDay);
    decided(s, "pass", now);
    ASSERT_EQ(s.prune(now - 30 * kDay, now - 30 * kDay).links, 5);
  };
  {
    test::TempDir t;
    pruned_store(t);
    ASSERT_TRUE(Store::verify_chain(t.str()).ok);
    tamper(t, "UPDATE chain_checkpoint SET hash = '" + std::string(64, 'f') + "'");
    const ChainReport r = Store::verify_chain(t.str());
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.problem.find("checkpoint"), std::string::npos) << r.problem;
  }
  {
    test::TempDir t;
    pruned_store(t);
    tamper(t, "DELETE FROM chain_checkpoint");
    const ChainReport r = Store::verify_chain(t.str());
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.problem.find("does not follow"), std::string::npos) << r.problem;
  }
  {
    // Records inside retention cannot be passed off as pruned: the rows are gone but their
    // links are not.
    test::TempDir t;
    pruned_store(t);
    tamper(t, "DELETE FROM fillets WHERE decided_ns >= " + std::to_string(now - kDay));
    const ChainReport r = Store::verify_chain(t.str());
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.problem.find("was removed from the store"), std::string::npos) << r.problem;
  }
}
