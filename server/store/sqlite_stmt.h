// A prepared SQLite statement that finalises itself; errors throw Error naming the SQL.
// Internal to the store's .cpp files.
#pragma once
#include <sqlite3.h>

#include <cstdint>
#include <string>

#include "core/error.h"

namespace rangex {

// SQLite's complaint, with a full disk named as one: that is what a plant's operator must
// act on (SQLITE_FULL reads "database or disk is full").
inline std::string store_error(sqlite3* db, int rc) {
  const std::string what = sqlite3_errmsg(db);
  return (rc & 0xff) == SQLITE_FULL ? "disk full: " + what : what;
}

class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &s_, nullptr) != SQLITE_OK)
      fail("store: cannot prepare '", sql, "': ", sqlite3_errmsg(db));
  }
  ~Stmt() { sqlite3_finalize(s_); }
  Stmt& bind(int i, int64_t v) {
    sqlite3_bind_int64(s_, i, v);
    return *this;
  }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(s_, i, v);
    return *this;
  }
  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.c_str(), int(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(s_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail("store: ", store_error(db_, rc));
  }
  int64_t i64(int c) const { return sqlite3_column_int64(s_, c); }
  bool null(int c) const { return sqlite3_column_type(s_, c) == SQLITE_NULL; }
  double dbl(int c) const { return sqlite3_column_double(s_, c); }
  std::string str(int c) const {
    const auto* t = sqlite3_column_text(s_, c);
    return t ? reinterpret_cast<const char*>(t) : "";
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* s_ = nullptr;
};

}  // namespace rangex
