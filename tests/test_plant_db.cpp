// The plant-wide PostgreSQL against a real server (tests/pg_instance.h): migrations, store
// and forward exactly once, through a stopped, a killed and a refused database.
#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <map>
#include <thread>

#include "core/error.h"
#include "pg_instance.h"
#include "plantdb/chain_check.h"
#include "plantdb/forwarder.h"
#include "plantdb/pg_connection.h"
#include "plantdb/pg_records.h"
#include "plantdb/plant_db_prune.h"
#include "plantdb/plant_db_schema.h"
#include "store/record_chain.h"
#include "store/store.h"
#include "temp_dir.h"
#include "wait_until.h"

using namespace rangex;
using rangex::test::PgInstance;
using rangex::test::TempDir;
using rangex::test::wait_until;

namespace {

StoredFillet fillet(int lane, int64_t n, bool reject) {
  StoredFillet f;
  f.lane = lane;
  f.lane_fillet = n;
  f.first_encoder = 1000 * n;
  f.rows = 400;
  f.decision = reject ? "reject" : "pass";
  f.reason = reject ? "1 bone fragment" : "";
  f.calibration_id = "cal \"quoted\" \\ and {braces}, commas";
  f.beta0 = 8.1234567890123456;
  f.beta1 = -0.0312345678901234;
  f.beta2 = 1e-5 / 3;
  f.resid_mean_dn = 0.1, f.resid_std_dn = 18.6, f.belt_y0_mm = 123.456;
  f.decided_ns = now_ns();
  if (reject)
    f.fragments.push_back({"round", 1.0 / 3, -2.5, 4.2, 7.77, 0.123, 1.9, 10, 14, 20, 25, 0});
  return f;
}

// Stores `n` fillets (every third a reject with an image) and an audit entry per ten.
void fill(Store& s, int n, int lane = 0) {
  for (int i = 0; i < n; ++i) {
    const int64_t uid = s.add_fillet(fillet(lane, i, i % 3 == 0));
    if (i % 3 == 0) s.add_image(uid, "xray", s.image_dir(uid) + "/xray.png");
    if (i % 10 == 0) s.audit("test", "note", "after fillet " + std::to_string(uid));
  }
}

int64_t count(PgConnection& db, const std::string& table, const std::string& server) {
  return db.exec("SELECT count(*) FROM " + table + " WHERE server_id = $1", {server}).i64(0, 0);
}

ForwarderOptions options(const PgInstance& pg, const std::string& id) {
  ForwarderOptions o;
  o.conninfo = pg.conninfo();
  o.server_id = id;
  o.host = "test-host";
  o.idle_s = 0.05;
  o.retry_max_s = 0.5;
  o.batch_links = 37;  // several batches for a few hundred records
  return o;
}

// Every local record is in PostgreSQL once, with the content the local chain hashed.
void expect_all_forwarded(Store& s, PgConnection& db, const std::string& id) {
  const ForwardBatch all = s.forward_batch(ForwardCursor{}, 1 << 20, true);
  EXPECT_EQ(count(db, "ledger", id), int64_t(all.links.size()));
  EXPECT_EQ(count(db, "fillets", id), int64_t(all.fillets.size()));
  EXPECT_EQ(count(db, "audit", id), int64_t(all.audit.size()));
  EXPECT_EQ(count(db, "images", id), int64_t(all.images.size()));
  int64_t fragments = 0;
  for (const StoredFillet& f : all.fillets) fragments += int64_t(f.fragments.size());
  EXPECT_EQ(count(db, "fragments", id), fragments);
  // The ledger's hashes, link by link, and each fillet's content read back from PostgreSQL.
  const PgRows links =
      db.exec("SELECT seq, hash FROM ledger WHERE server_id = $1 ORDER BY seq", {id});
  ASSERT_EQ(links.rows(), int(all.links.size()));
  for (int i = 0; i < links.rows(); ++i) {
    EXPECT_EQ(links.i64(i, 0), all.links[size_t(i)].seq);
    EXPECT_EQ(links.str(i, 1), all.links[size_t(i)].hash);
  }
  std::vector<int64_t> uids;
  for (const StoredFillet& f : all.fillets) uids.push_back(f.uid);
  const std::map<int64_t, StoredFillet> back = pg_fillets(db, id, uids);
  ASSERT_EQ(back.size(), all.fillets.size());
  for (const StoredFillet& f : all.fillets)
    EXPECT_EQ(chain_content(back.at(f.uid)), chain_content(f)) << "fillet " << f.uid;
}

class PlantDb : public ::testing::Test {
 protected:
  void SetUp() override {
    db = std::make_unique<PgConnection>(pg.conninfo());
    plant_db_migrate(*db);
  }
  PgInstance pg;
  std::unique_ptr<PgConnection> db;
};

}  // namespace

TEST(PlantDbSchema, MigratesAnEmptyDatabaseAndThePreviousVersion) {
  PgInstance pg;
  PgConnection db(pg.conninfo());
  EXPECT_EQ(plant_db_schema_version(db), 0);
  // A running server never migrates: it names the command.
  try {
    require_plant_db_schema(db);
    FAIL() << "an empty database was accepted";
  } catch (const FailedPrecondition& e) {
    EXPECT_NE(std::string(e.what()).find("rangexctl db migrate"), std::string::npos) << e.what();
  }
  // The previous version first, with a record in it; then the rest.
  EXPECT_EQ(plant_db_migrate(db, 1), 1);
  EXPECT_EQ(plant_db_schema_version(db), 1);
  db.exec("INSERT INTO servers (server_id, host) VALUES ('old', 'h')");
  std::vector<int> applied;
  EXPECT_EQ(plant_db_migrate(db, 0, [&](const Migration& m) { applied.push_back(m.version); }),
            plant_db_schema_version_needed() - 1);
  EXPECT_EQ(applied.front(), 2);
  EXPECT_EQ(plant_db_schema_version(db), plant_db_schema_version_needed());
  EXPECT_NO_THROW(require_plant_db_schema(db));
  EXPECT_EQ(db.exec("SELECT host FROM servers WHERE server_id = 'old'").str(0, 0), "h");
  // Again: nothing to do.
  EXPECT_EQ(plant_db_migrate(db), 0);
  // A database newer than this build is refused, not rolled back.
  db.exec("INSERT INTO rangex_schema VALUES (99, 'from the future', 0)");
  EXPECT_THROW(plant_db_migrate(db), Error);
  EXPECT_THROW(require_plant_db_schema(db), FailedPrecondition);
}

TEST_F(PlantDb, EverythingStoredIsForwardedExactlyOnce) {
  TempDir dir;
  Store s(dir.str());
  fill(s, 120);
  s.add_setting(SettingKind::kCalibration, {0, "cal-1", "xray: {}", now_ns(), false, "{}"});
  s.set_active_setting(SettingKind::kCalibration, 0, "cal-1");
  s.audit("test", "calibration.activate", "lane 0 id cal-1");
  {
    Forwarder f(s, options(pg, "srv-a"));
    f.start();
    ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
    EXPECT_EQ(f.status().lag_records, 0);
  }
  expect_all_forwarded(s, *db, "srv-a");
  auto active = [&](const char* cal) {
    return db->exec("SELECT active FROM settings WHERE server_id = 'srv-a' AND id = $1", {cal})
        .str(0, 0);
  };
  EXPECT_EQ(active("cal-1"), "t");
  {
    // An activation while the line is idle reaches the database without waiting for the
    // next decision.
    Forwarder f(s, options(pg, "srv-a"));
    f.start();
    ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
    s.add_setting(SettingKind::kCalibration, {0, "cal-2", "xray: {}", now_ns(), false, "{}"});
    s.set_active_setting(SettingKind::kCalibration, 0, "cal-2");
    s.audit("test", "calibration.activate", "lane 0 id cal-2");
    EXPECT_TRUE(wait_until(30, [&] { return active("cal-2") == "t" && active("cal-1") == "f"; }));
  }
  // The database's cursor set back (a batch whose commit was never acknowledged): the
  // records come again and change nothing.
  db->exec("UPDATE servers SET forwarded_seq = 0, image_seq = 0 WHERE server_id = 'srv-a'");
  fill(s, 10);
  {
    Forwarder f(s, options(pg, "srv-a"));
    f.start();
    ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
  }
  expect_all_forwarded(s, *db, "srv-a");
  // The local copy of the cursor is what retention keeps after.
  EXPECT_EQ(s.forwarded().seq, s.head_seq());
}

TEST_F(PlantDb, InspectionGoesOnWhileTheDatabaseIsDownAndNothingIsLostOrDoubled) {
  TempDir dir;
  Store s(dir.str());
  Forwarder f(s, options(pg, "srv-b"));
  f.start();
  fill(s, 30);
  ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
  pg.stop();
  fill(s, 60);  // stored while PostgreSQL is down: the store does not wait
  ASSERT_TRUE(wait_until(30, [&] { return !f.status().connected; }));
  ASSERT_TRUE(wait_until(30, [&] { return f.status().lag_records >= 60; }))
      << f.status().lag_records;
  EXPECT_EQ(f.status().state, "unreachable");
  EXPECT_NE(f.status().last_error.find("PostgreSQL"), std::string::npos) << f.status().last_error;
  // Retention prunes nothing the database lacks, even with every record past its time.
  const int64_t head = s.head_seq();
  const PruneReport p = s.prune(now_ns() + int64_t(86400e9), now_ns() + int64_t(86400e9));
  EXPECT_LE(p.checkpoint_seq, s.forwarded().seq);
  EXPECT_GT(head - p.checkpoint_seq, 60);
  pg.start();
  ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
  db = std::make_unique<PgConnection>(pg.conninfo());
  // What was pruned locally had been forwarded before: PostgreSQL holds every link, the
  // retention pass's own audit entries included, each once.
  const int64_t now_head = s.head_seq();
  EXPECT_GT(now_head, head);
  EXPECT_EQ(count(*db, "ledger", "srv-b"), now_head);
  EXPECT_EQ(db->exec("SELECT count(DISTINCT seq) FROM ledger WHERE server_id = 'srv-b'").i64(0, 0),
            now_head);
}

TEST_F(PlantDb, APostgresKilledMidTransactionLosesAndDoublesNothing) {
  TempDir dir;
  Store s(dir.str());
  Forwarder f(s, options(pg, "srv-c"));
  f.start();
  std::atomic<bool> done{false};
  std::thread writer([&] {
    fill(s, 300);
    done = true;
  });
  ASSERT_TRUE(wait_until(30, [&] { return f.status().links > 40; }));
  pg.kill9();  // while batches are being written
  ASSERT_TRUE(wait_until(30, [&] { return !f.status().connected; }));
  pg.start();
  writer.join();
  ASSERT_TRUE(f.wait_caught_up(90)) << f.status().last_error;
  db = std::make_unique<PgConnection>(pg.conninfo());
  expect_all_forwarded(s, *db, "srv-c");
  EXPECT_GE(f.status().failures, 1);
}

// A database that takes the connection and answers nothing (a hung host): the forwarder's
// statement waits on it, and a stop must still end, the records left in the store for the
// next forwarder.
TEST_F(PlantDb, ADatabaseThatAnswersNothingHoldsNoStop) {
  TempDir dir;
  Store s(dir.str());
  auto f = std::make_unique<Forwarder>(s, options(pg, "srv-h"));
  f->start();
  fill(s, 10);
  ASSERT_TRUE(f->wait_caught_up(60)) << f->status().last_error;
  pg.freeze();
  fill(s, 10);  // the next batch's statements wait for an answer
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  auto stopped = std::async(std::launch::async, [&] { f->stop(); });
  const bool ended = stopped.wait_for(std::chrono::seconds(30)) == std::future_status::ready;
  pg.thaw();  // a stop still waiting ends now, so that the test fails rather than hangs
  stopped.get();
  EXPECT_TRUE(ended) << "the forwarder's stop waited 30 s on a database that answers nothing";
  f.reset();
  Forwarder again(s, options(pg, "srv-h"));
  again.start();
  ASSERT_TRUE(again.wait_caught_up(60)) << again.status().last_error;
  again.stop();
  db = std::make_unique<PgConnection>(pg.conninfo());
  expect_all_forwarded(s, *db, "srv-h");
}

// One connection to a host that answers nothing: the statement fails within its bound,
// naming the database, and the connection is closed (nobody knows what the statement did).
// Several statements in one string keep PQexec's answer: the last result, or the first
// failure.
TEST_F(PlantDb, AStatementWithNoAnswerFailsWithinItsBound) {
  PgConnection c(pg.conninfo(), 5, 1);
  EXPECT_EQ(c.exec("SELECT 1; SELECT 2").str(0, 0), "2");
  try {
    c.exec("SELECT 1; SELECT no_such_column; SELECT 3");
    ADD_FAILURE() << "a failed statement among three was not reported";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_column"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(c.ok());
  pg.freeze();
  auto answered = std::async(std::launch::async, [&]() -> std::string {
    try {
      c.exec("SELECT 1");
      return "answered";
    } catch (const Unavailable& e) {
      return e.what();
    }
  });
  const bool ended = answered.wait_for(std::chrono::seconds(60)) == std::future_status::ready;
  pg.thaw();  // a statement still waiting gets its answer now, so that the test fails
  const std::string why = answered.get();
  EXPECT_TRUE(ended) << "a statement waited 60 s on a database that answers nothing";
  EXPECT_EQ(why.rfind("PostgreSQL at " + pg_where(pg.conninfo()) + ": ", 0), 0u) << why;
  EXPECT_NE(why.find("'SELECT 1': no answer within 6 s"), std::string::npos) << why;
  EXPECT_FALSE(c.ok());
  EXPECT_EQ(c.unanswered(), why);
  EXPECT_THROW(c.exec("SELECT 1"), Unavailable);
  EXPECT_EQ(PgConnection(pg.conninfo()).exec("SELECT 1").str(0, 0), "1");
}

// The same hung host while rangexd runs: the forwarder's statement fails within its bound,
// its status says why, and once the database answers it carries on, each record once.
TEST_F(PlantDb, AForwarderOnAHungDatabaseSaysSoAndResumesWhenItAnswers) {
  TempDir dir;
  Store s(dir.str());
  ForwarderOptions o = options(pg, "srv-n");
  o.statement_timeout_s = 1;
  Forwarder f(s, o);
  f.start();
  fill(s, 10);
  ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
  pg.freeze();
  fill(s, 10);
  const bool named = test::wait_until(
      60, [&] { return f.status().last_error.find("no answer within 6 s") != std::string::npos; });
  const ForwarderStatus held = f.status();
  pg.thaw();
  EXPECT_TRUE(named) << held.last_error;
  EXPECT_FALSE(held.connected);
  EXPECT_GT(held.lag_records, 0);
  ASSERT_TRUE(f.wait_caught_up(60)) << f.status().last_error;
  f.stop();
  expect_all_forwarded(s, *db, "srv-n");
}

TEST_F(PlantDb, TwoServersWithOneIdAndANewStoreUnderAnOldIdAreRefused) {
  TempDir d1, d2, d3;
  Store s1(d1.str()), s2(d2.str());
  fill(s1, 20);
  fill(s2, 5);
  Forwarder f1(s1, options(pg, "line-1"));
  f1.start();
  ASSERT_TRUE(f1.wait_caught_up(60)) << f1.status().last_error;
  Forwarder f2(s2, options(pg, "line-1"));
  f2.start();
  ASSERT_TRUE(wait_until(30, [&] { return f2.status().state == "refused"; }));
  EXPECT_NE(f2.status().last_error.find("already forwarding"), std::string::npos)
      << f2.status().last_error;
  f2.stop();
  f1.stop();
  // line-1's records are s1's: a store started afresh under that id is refused.
  Store s3(d3.str());
  fill(s3, 3);
  Forwarder f3(s3, options(pg, "line-1"));
  f3.start();
  ASSERT_TRUE(wait_until(30, [&] { return f3.status().state == "refused"; }));
  EXPECT_NE(f3.status().last_error.find("not this store's"), std::string::npos)
      << f3.status().last_error;
  f3.stop();
  EXPECT_EQ(count(*db, "fillets", "line-1"), 20);
}

TEST_F(PlantDb, EveryServersChainVerifiesAndAnUpdateBehindRangexsBackIsNamed) {
  TempDir d1, d2;
  Store s1(d1.str()), s2(d2.str());
  fill(s1, 40);
  fill(s2, 25, 1);
  {
    Forwarder f1(s1, options(pg, "srv-1")), f2(s2, options(pg, "srv-2"));
    f1.start();
    f2.start();
    ASSERT_TRUE(f1.wait_caught_up(60)) << f1.status().last_error;
    ASSERT_TRUE(f2.wait_caught_up(60)) << f2.status().last_error;
  }
  std::vector<ServerChainReport> r = verify_plant_db_chains(*db);
  ASSERT_EQ(r.size(), 2u);
  for (const ServerChainReport& c : r) EXPECT_TRUE(c.ok) << c.server_id << ": " << c.problem;
  EXPECT_EQ(r[0].links, s1.head_seq());
  EXPECT_EQ(r[0].head, s1.chain_head());
  // A reject turned into a pass in PostgreSQL: srv-1's chain breaks at that fillet's link,
  // srv-2's still holds.
  const PgRows victim = db->exec(
      "SELECT l.seq, f.uid FROM fillets f JOIN ledger l ON l.server_id = f.server_id AND l.kind "
      "= 'fillet' AND l.ref = f.uid WHERE f.server_id = 'srv-1' AND f.decision = 'reject' ORDER "
      "BY f.uid LIMIT 1 OFFSET 3");
  db->exec(
      "UPDATE fillets SET decision = 'pass', reason = '' WHERE server_id = 'srv-1' AND uid "
      "= $1",
      {victim.str(0, 1)});
  r = verify_plant_db_chains(*db);
  EXPECT_FALSE(r[0].ok);
  EXPECT_EQ(r[0].first_broken_seq, victim.i64(0, 0));
  EXPECT_NE(r[0].problem.find("changed"), std::string::npos) << r[0].problem;
  EXPECT_TRUE(r[1].ok);
  // An audit entry removed from srv-2's: the link that named it is the first broken one.
  db->exec(
      "DELETE FROM audit WHERE server_id = 'srv-2' AND row_id = (SELECT min(row_id) FROM "
      "audit WHERE server_id = 'srv-2')");
  r = verify_plant_db_chains(*db);
  EXPECT_FALSE(r[1].ok);
  EXPECT_NE(r[1].problem.find("missing"), std::string::npos) << r[1].problem;
}

TEST_F(PlantDb, PruneDropsWholeDaysAndEachChainStartsAfterItsLastDroppedLink) {
  TempDir d1, d2;
  Store s1(d1.str()), s2(d2.str());
  constexpr int64_t kDay = 86'400'000'000'000;
  const int64_t now = now_ns();
  // srv-1: a fillet 5, 4 and 3 days ago and one today; srv-2: one 4 days ago and one today.
  auto add = [&](Store& s, int64_t decided_ns, bool reject) {
    StoredFillet f = fillet(0, s.head_seq(), reject);
    f.decided_ns = decided_ns;
    const int64_t uid = s.add_fillet(f);
    if (reject) s.add_image(uid, "xray", s.image_dir(uid) + "/xray.png");
  };
  for (int days : {5, 4, 3}) add(s1, now - days * kDay, days == 4);
  add(s1, now, false);
  add(s2, now - 4 * kDay, true);
  add(s2, now, false);
  auto forward = [&] {
    Forwarder f1(s1, options(pg, "srv-1")), f2(s2, options(pg, "srv-2"));
    f1.start();
    f2.start();
    ASSERT_TRUE(f1.wait_caught_up(60)) << f1.status().last_error;
    ASSERT_TRUE(f2.wait_caught_up(60)) << f2.status().last_error;
  };
  forward();
  const std::string yesterday = utc_day(now - kDay);
  // A dry run drops nothing and says what it would.
  PlantDbPruneReport dry = plant_db_prune(*db, yesterday, true, "test");
  EXPECT_EQ(dry.partitions.size(), 15u);  // 3 days x 5 tables
  EXPECT_EQ(count(*db, "fillets", "srv-1"), 4);
  // A broken chain is evidence: nothing is dropped while a dropped link does not verify.
  db->exec(
      "UPDATE fillets SET decision = 'pass' WHERE server_id = 'srv-2' AND decision = 'reject'");
  try {
    plant_db_prune(*db, yesterday, false, "test");
    FAIL() << "a broken chain was pruned";
  } catch (const FailedPrecondition& e) {
    EXPECT_NE(std::string(e.what()).find("srv-2's chain is broken at link 1"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(count(*db, "fillets", "srv-2"), 2);
  db->exec("UPDATE fillets SET decision = 'reject' WHERE server_id = 'srv-2' AND uid = 1");
  const PlantDbPruneReport r = plant_db_prune(*db, yesterday, false, "test");
  EXPECT_EQ(r.before, yesterday);
  EXPECT_EQ(r.partitions.size(), 15u);
  EXPECT_EQ(r.fillets, 4);
  ASSERT_EQ(r.checkpoints.size(), 2u);
  EXPECT_EQ(r.checkpoints[0].server_id, "srv-1");
  EXPECT_EQ(r.checkpoints[0].seq, 3);
  EXPECT_EQ(r.checkpoints[0].hash, *s1.link_hash(3));
  EXPECT_EQ(count(*db, "fillets", "srv-1"), 1);
  EXPECT_EQ(count(*db, "images", "srv-1"), 0);
  EXPECT_EQ(db->exec("SELECT count(*) FROM prunes").i64(0, 0), 1);
  // Each chain verifies from its checkpoint to the store's head.
  std::vector<ServerChainReport> v = verify_plant_db_chains(*db);
  ASSERT_EQ(v.size(), 2u);
  for (const ServerChainReport& c : v) EXPECT_TRUE(c.ok) << c.server_id << ": " << c.problem;
  EXPECT_EQ(v[0].first_seq, 4);
  EXPECT_EQ(v[0].head, s1.chain_head());
  EXPECT_EQ(v[1].head, s2.chain_head());
  // srv-1's clock stepped back 4 days: its next link is stamped on a day before the cutoff
  // although links after the checkpoint are kept. Dropping it would cut the chain, so the
  // cutoff moves back to that day and nothing of it goes.
  add(s1, now - 4 * kDay, false);
  add(s1, now, false);
  forward();
  const PlantDbPruneReport r2 = plant_db_prune(*db, yesterday, false, "test");
  EXPECT_EQ(r2.asked_before, yesterday);
  EXPECT_EQ(r2.before, utc_day(now - 4 * kDay));
  EXPECT_TRUE(r2.partitions.empty());
  EXPECT_EQ(count(*db, "fillets", "srv-1"), 3);
  v = verify_plant_db_chains(*db);
  for (const ServerChainReport& c : v) EXPECT_TRUE(c.ok) << c.server_id << ": " << c.problem;
  EXPECT_EQ(v[0].links, 3);
  // What is not a day is refused.
  EXPECT_THROW(plant_db_prune(*db, "not-a-day", false, "test"), Error);
}
