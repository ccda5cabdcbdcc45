// The store's versioned lane settings: calibration sets and learned inspection settings,
// immutable once added, one active per lane and kind.
#include <sqlite3.h>

#include "core/error.h"
#include "store/record_chain.h"
#include "store/sqlite_stmt.h"
#include "store/store.h"

namespace rangex {

namespace {
const char* table_of(SettingKind k) {
  return k == SettingKind::kCalibration ? "calibrations" : "learned_settings";
}
const char* noun_of(SettingKind k) {
  return k == SettingKind::kCalibration ? "a calibration" : "learned settings";
}
}  // namespace

void Store::add_setting(SettingKind kind, const StoredSetting& c) {
  std::lock_guard<std::mutex> lock(mu_);
  const std::string table = table_of(kind);
  {
    Stmt e(db_, ("SELECT 1 FROM " + table + " WHERE lane = ? AND id = ?").c_str());
    e.bind(1, int64_t(c.lane)).bind(2, c.id);
    if (e.step())
      fail_exists("lane ", c.lane, " already has ", noun_of(kind), " '", c.id,
                  "' (versions are immutable)");
  }
  Stmt q(db_, ("INSERT INTO " + table +
               " (lane, id, yaml, uploaded_ns, active, report) VALUES (?,?,?,?,?,?)")
                  .c_str());
  q.bind(1, int64_t(c.lane))
      .bind(2, c.id)
      .bind(3, c.yaml)
      .bind(4, c.uploaded_ns)
      .bind(5, int64_t(c.active))
      .bind(6, c.report);
  q.step();
}

std::vector<StoredSetting> Store::settings(SettingKind kind, int lane) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, (std::string("SELECT lane, id, yaml, uploaded_ns, active, report FROM ") +
               table_of(kind) + " WHERE (? < 0 OR lane = ?) ORDER BY lane, uploaded_ns")
                  .c_str());
  q.bind(1, int64_t(lane)).bind(2, int64_t(lane));
  std::vector<StoredSetting> out;
  while (q.step())
    out.push_back({int(q.i64(0)), q.str(1), q.str(2), q.i64(3), q.i64(4) != 0, q.str(5)});
  return out;
}

std::optional<StoredSetting> Store::setting(SettingKind kind, int lane, const std::string& id) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt q(db_, (std::string("SELECT lane, id, yaml, uploaded_ns, active, report FROM ") +
               table_of(kind) + " WHERE lane = ? AND id = ?")
                  .c_str());
  q.bind(1, int64_t(lane)).bind(2, id);
  if (!q.step()) return std::nullopt;
  return StoredSetting{int(q.i64(0)), q.str(1), q.str(2), q.i64(3), q.i64(4) != 0, q.str(5)};
}

void Store::set_active_setting(SettingKind kind, int lane, const std::string& id) {
  std::lock_guard<std::mutex> lock(mu_);
  Stmt a(
      db_,
      (std::string("UPDATE ") + table_of(kind) + " SET active = (id = ?) WHERE lane = ?").c_str());
  a.bind(1, id).bind(2, int64_t(lane));
  a.step();
}

void Store::add_calibration(const StoredCalibration& c) {
  add_setting(SettingKind::kCalibration, c);
}
std::vector<StoredCalibration> Store::calibrations(int lane) {
  return settings(SettingKind::kCalibration, lane);
}
std::optional<StoredCalibration> Store::calibration(int lane, const std::string& id) {
  return setting(SettingKind::kCalibration, lane, id);
}
void Store::set_active_calibration(int lane, const std::string& id) {
  set_active_setting(SettingKind::kCalibration, lane, id);
}

}  // namespace rangex
