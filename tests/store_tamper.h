// Runs SQL on a store's file from outside, as someone editing it behind rangexd's back would.
#pragma once
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <string>

#include "temp_dir.h"

namespace rangex::test {

inline void tamper(const TempDir& t, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((t.str() + "/rangex.sqlite").c_str(), &db), SQLITE_OK);
  char* err = nullptr;
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << err;
  sqlite3_close(db);
}

}  // namespace rangex::test
