// The store keeps every field of a decision, and opens stores written by earlier versions.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "store/store.h"
#include "temp_dir.h"

using namespace rangex;

namespace {
StoredFillet sample() {
  StoredFillet f;
  f.lane = 2;
  f.lane_fillet = 7;
  f.first_encoder = 1234;
  f.rows = 300;
  f.decision = "reject";
  f.reason = "1 bone fragment";
  f.beta0 = 8.2, f.beta1 = -0.031, f.beta2 = 1.5e-4;
  f.resid_mean_dn = 0.5, f.resid_std_dn = 21.0, f.belt_y0_mm = 400.0;
  f.calibration_id = "cal-1";
  f.decided_ns = 99;
  f.fragments.push_back({"bone", 1.0, 2.0, 3.5, -12.0, 0.8, 3.7});
  return f;
}
}  // namespace

TEST(Store, RoundTripsTheParabolaAndTheFragmentsContrast) {
  test::TempDir t;
  Store s(t.str());
  const int64_t uid = s.add_fillet(sample());
  const auto f = s.fillet(uid);
  ASSERT_TRUE(f);
  EXPECT_DOUBLE_EQ(f->beta2, 1.5e-4);
  ASSERT_EQ(f->fragments.size(), 1u);
  EXPECT_DOUBLE_EQ(f->fragments[0].meat_mm, 3.7);
  EXPECT_DOUBLE_EQ(f->fragments[0].attenuation_mm2, 0.8);
  const auto listed = s.list_fillets(0, 0, -1, 0, 10);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_DOUBLE_EQ(listed[0].fragments[0].meat_mm, 3.7);
}

TEST(Store, OpensAStoreFromBeforeTheParabola) {
  test::TempDir t;
  {
    // The schema as the versions before beta2 and meat_mm wrote it, with one row.
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(t.str("rangex.sqlite").c_str(), &db), SQLITE_OK);
    const char* sql =
        "CREATE TABLE fillets (uid INTEGER PRIMARY KEY AUTOINCREMENT, lane INTEGER, "
        "lane_fillet INTEGER, first_encoder INTEGER, rows INTEGER, decision TEXT, reason TEXT, "
        "beta0 REAL, beta1 REAL, resid_mean_dn REAL, resid_std_dn REAL, calibration_id TEXT, "
        "decided_ns INTEGER, belt_y0_mm REAL);"
        "CREATE TABLE fragments (fillet_uid INTEGER, kind TEXT, x_mm REAL, y_mm REAL, "
        "area_mm2 REAL, peak_z REAL, attenuation_mm2 REAL);"
        "INSERT INTO fillets VALUES (1, 0, 1, 10, 200, 'reject', 'r', 8.1, -0.03, 0, 20, 'c', 5, "
        "1.0);"
        "INSERT INTO fragments VALUES (1, 'bone', 1, 2, 3, -9, 0.5);";
    ASSERT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  Store s(t.str());
  const auto old = s.fillet(1);
  ASSERT_TRUE(old);
  EXPECT_DOUBLE_EQ(old->beta1, -0.03);
  EXPECT_DOUBLE_EQ(old->beta2, 0.0);
  ASSERT_EQ(old->fragments.size(), 1u);
  EXPECT_DOUBLE_EQ(old->fragments[0].meat_mm, 0.0);
  EXPECT_DOUBLE_EQ(old->fragments[0].attenuation_mm2, 0.5);
  const auto f = s.fillet(s.add_fillet(sample()));
  ASSERT_TRUE(f);
  EXPECT_DOUBLE_EQ(f->beta2, 1.5e-4);
  EXPECT_DOUBLE_EQ(f->fragments[0].meat_mm, 3.7);
}

namespace {
// Overwrites the page type of `table`'s root page with a value no page has, as a torn write or
// a bad sector would leave it.
void break_root_page(const test::TempDir& t, const std::string& table) {
  const std::string path = t.str() + "/rangex.sqlite";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* q = nullptr;
  ASSERT_EQ(
      sqlite3_prepare_v2(db, "SELECT rootpage FROM sqlite_master WHERE name = ?", -1, &q, nullptr),
      SQLITE_OK);
  sqlite3_bind_text(q, 1, table.c_str(), -1, SQLITE_TRANSIENT);
  ASSERT_EQ(sqlite3_step(q), SQLITE_ROW);
  const int64_t root = sqlite3_column_int64(q, 0);
  sqlite3_finalize(q);
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA page_size", -1, &q, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(q), SQLITE_ROW);
  const int64_t page = sqlite3_column_int64(q, 0);
  sqlite3_finalize(q);
  sqlite3_close(db);
  ASSERT_GT(root, 1);
  std::FILE* f = std::fopen(path.c_str(), "r+b");
  ASSERT_NE(f, nullptr);
  std::fseek(f, long((root - 1) * page), SEEK_SET);
  const unsigned char bad[4] = {0x7f, 0x7f, 0x7f, 0x7f};
  std::fwrite(bad, 1, sizeof bad, f);
  std::fclose(f);
}
}  // namespace

TEST(Store, ADamagedTableIsRefusedAtStartAndByTheAuditNamingIt) {
  for (const char* table : {"fillets", "fragments", "images", "calibrations", "audit"}) {
    SCOPED_TRACE(table);
    test::TempDir t;
    {
      Store s(t.str());
      const int64_t uid = s.add_fillet(sample());
      s.add_image(uid, "overlay", "images/1.png");
      s.add_calibration({2, "cal-1", "laser_plane: {offset_mm: 0}\n", 1, false, ""});
      s.audit("test", "store.test", "a row in every table");
    }
    EXPECT_TRUE(Store::verify_chain(t.str()).ok);
    break_root_page(t, table);
    try {
      Store s(t.str());
      ADD_FAILURE() << "a store with a damaged " << table << " table opened";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("the store is damaged (table " + std::string(table) + ":"),
                std::string::npos)
          << what;
    }
    const ChainReport r = Store::verify_chain(t.str());
    EXPECT_FALSE(r.ok);
    EXPECT_TRUE(r.damaged);
    EXPECT_NE(r.problem.find("table " + std::string(table) + ":"), std::string::npos) << r.problem;
  }
}

TEST(Store, AFullDiskIsNamedAsOneAndTheStoreWritesAgainOnceThereIsRoom) {
  test::TempDir t;
  Store s(t.str());
  s.add_fillet(sample());
  // No room left (SQLITE_FULL, as on a full disk): the error names it, not the ROLLBACK
  // that SQLite made itself ("cannot rollback - no transaction is active").
  s.cap_pages_for_tests(1);
  StoredFillet big = sample();
  big.reason.assign(64 << 10, 'x');  // more than the pages the store has free
  try {
    s.add_fillet(big);
    ADD_FAILURE() << "a fillet was stored with no room left";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("disk full"), std::string::npos) << what;
    EXPECT_EQ(what.find("cannot rollback"), std::string::npos) << what;
  }
  s.cap_pages_for_tests(1 << 20);
  const int64_t uid = s.add_fillet(big);
  EXPECT_EQ(s.fillet(uid)->reason.size(), size_t(64 << 10));
  EXPECT_EQ(s.list_fillets(0, 0, -1, 0, 10).size(), 2u);
  EXPECT_TRUE(Store::verify_chain(t.str()).ok);
}

// A reject's decision and its images are stored together or not at all. Before, the
// decision was committed first; a full disk then failed the images' registration, rangexd
// stopped, and after the restart the fillet stood decided with one image of four (a
// restarted rangexd does not decide a stored fillet again).
TEST(Store, ADecisionAndItsImagesAreStoredTogetherOrNotAtAll) {
  test::TempDir t;
  Store s(t.str());
  s.add_fillet(sample());
  StoredFillet reject = sample();
  reject.reason.assign(64 << 10, 'x');  // more than the pages the store has free below
  const std::string staged = s.staging_dir(reject);
  std::filesystem::create_directories(staged);
  for (const char* kind : {"overlay", "xray", "thickness", "residual"})
    std::ofstream(staged + "/" + kind + ".png") << kind;
  s.cap_pages_for_tests(1);
  EXPECT_THROW(s.add_fillet(reject, staged), Error);
  // Nothing of it stored; its images wait where they were staged.
  EXPECT_EQ(s.list_fillets(0, 0, -1, 0, 10).size(), 1u);
  EXPECT_TRUE(std::filesystem::exists(staged + "/xray.png"));
  s.cap_pages_for_tests(1 << 20);
  const int64_t uid = s.add_fillet(reject, staged);
  EXPECT_EQ(s.list_fillets(0, 0, -1, 0, 10).size(), 2u);
  EXPECT_FALSE(std::filesystem::exists(staged));
  for (const char* kind : {"overlay", "xray", "thickness", "residual"}) {
    const auto path = s.image_path(uid, kind);
    ASSERT_TRUE(path) << kind;
    EXPECT_EQ(*path, s.image_dir(uid) + "/" + kind + ".png");
    std::ifstream in(*path);
    std::string body;
    in >> body;
    EXPECT_EQ(body, kind);
  }
  EXPECT_TRUE(Store::verify_chain(t.str()).ok);
}

TEST(Store, ImagesStagedForDecisionsNotStoredAreGoneWhenItOpensAgain) {
  test::TempDir t;
  std::string staged, image;
  {
    Store s(t.str());
    const int64_t uid = s.add_fillet(sample());
    std::filesystem::create_directories(s.image_dir(uid));
    image = s.image_dir(uid) + "/xray.png";
    std::ofstream(image) << "whole";
    s.add_image(uid, "xray", image);
    // The process is made to exit while it writes a decision's images (a full disk past
    // exit_after_s): one image whole, one cut off in its .part.
    staged = s.staging_dir(sample());
    std::filesystem::create_directories(staged);
    std::ofstream(staged + "/overlay.png") << "overlay";
    std::ofstream(staged + "/xray.png.part") << "xr";
  }
  Store s(t.str());
  EXPECT_FALSE(std::filesystem::exists(staged));
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::path(staged).parent_path()));
  EXPECT_TRUE(std::filesystem::exists(image));  // stored images stay
  EXPECT_EQ(s.list_fillets(0, 0, -1, 0, 10).size(), 1u);
}

// One writer to a data directory: a second rangexd given the same --data had started and
// removed the first's staged images. Another process's store is refused naming its pid, and
// its lock goes with it however it ends (here SIGKILL).
TEST(Store, AStoreAnotherProcessHasOpenIsRefusedNamingIt) {
  test::TempDir t;
  {
    Store first(t.str());
    try {
      Store second(t.str());
      ADD_FAILURE() << "two stores opened one directory";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("the store is in use by another process (pid " +
                                           std::to_string(getpid()) + ")"),
                std::string::npos)
          << e.what();
    }
  }
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  if (child == 0) {
    Store held(t.str());
    [[maybe_unused]] const ssize_t n = write(ready[1], "x", 1);
    pause();
    _exit(0);
  }
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1);
  try {
    Store refused(t.str());
    ADD_FAILURE() << "a store another process holds opened";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(pid " + std::to_string(child) + ")"), std::string::npos)
        << e.what();
  }
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  close(ready[0]);
  close(ready[1]);
  Store after(t.str());
  EXPECT_GT(after.add_fillet(sample()), 0);
}
