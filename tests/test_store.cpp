// The store keeps every field of a decision, and opens stores written by earlier versions.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include "service/store.h"
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
