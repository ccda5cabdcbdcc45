// The server's durable store: an embedded SQLite database of fillet results, fragments,
// image files, calibration versions and an audit log of every control-plane change. Images
// live as PNG files beside the database; the database holds their paths.
#pragma once
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/inspection.h"

struct sqlite3;

namespace rangex {

struct StoredFragment {
  std::string kind;
  double x_mm, y_mm, area_mm2, peak_z, attenuation_mm2;
  double meat_mm = 0;                          // peak excess attenuation in mm of the fillet's meat
  int row0 = 0, row1 = 0, col0 = 0, col1 = 0;  // bounding box in the fillet's images
};

struct StoredFillet {
  int64_t uid = 0;
  int lane = 0;
  int64_t lane_fillet = 0, first_encoder = 0;
  int rows = 0;
  std::string decision, reason, calibration_id;
  double beta0 = 0, beta1 = 0, beta2 = 0, resid_mean_dn = 0, resid_std_dn = 0, belt_y0_mm = 0;
  int64_t decided_ns = 0;
  std::vector<StoredFragment> fragments;
};

struct StoredCalibration {
  int lane = 0;
  std::string id, yaml;
  int64_t uploaded_ns = 0;
  bool active = false;
  std::string report;  // the solvers' JSON report; empty when none came with it
};

// Fillets decided in [from_ns, to_ns) (to_ns 0: no bound), on `lane` (-1: all), with
// `decision` ("": any), uid > after, oldest first, at most `limit`.
struct FilletQuery {
  int64_t from_ns = 0, to_ns = 0;
  int lane = -1;
  std::string decision;
  int64_t after = 0;
  int limit = 1000;
  bool newest_first = false;  // the latest `limit` matches, newest first (after is ignored)
};

struct AuditEntry {
  int64_t ts_ns = 0;
  std::string who, what, detail;
};

class Store {
 public:
  // Opens (creating if needed) <dir>/rangex.sqlite and <dir>/images/.
  explicit Store(const std::string& dir);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  int64_t add_fillet(const StoredFillet& f);  // returns the uid
  void add_image(int64_t uid, const std::string& kind, const std::string& path);
  std::string image_dir(int64_t uid) const;
  std::optional<std::string> image_path(int64_t uid, const std::string& kind);
  std::optional<StoredFillet> fillet(int64_t uid);
  // Decided in [from_ns, to_ns) (to_ns 0: no bound), lane -1 for all, uid > after, oldest first.
  std::vector<StoredFillet> list_fillets(int64_t from_ns, int64_t to_ns, int lane, int64_t after,
                                         int limit);
  std::vector<StoredFillet> list_fillets(const FilletQuery& q);
  int64_t count_fillets();

  void add_calibration(const StoredCalibration& c);       // throws Error if (lane, id) exists
  std::vector<StoredCalibration> calibrations(int lane);  // lane -1: all
  std::optional<StoredCalibration> calibration(int lane, const std::string& id);
  void set_active_calibration(int lane, const std::string& id);

  void audit(const std::string& who, const std::string& what, const std::string& detail);
  std::vector<std::string> audit_log(int limit);     // "ts who what detail", newest last
  std::vector<AuditEntry> audit_entries(int limit);  // the same, field by field

 private:
  void exec(const std::string& sql);
  void add_column(const std::string& table, const std::string& column, const std::string& decl);
  std::string dir_;
  sqlite3* db_ = nullptr;
  std::mutex mu_;
};

int64_t now_ns();

}  // namespace rangex
