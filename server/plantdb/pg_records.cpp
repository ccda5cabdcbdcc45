#include "plantdb/pg_records.h"

#include "plantdb/pg_array.h"
#include "plantdb/pg_connection.h"

namespace rangex {

namespace {
std::string id_array(const std::vector<int64_t>& ids) {
  PgArray a;
  for (int64_t v : ids) a.add(v);
  return a.text();
}
}  // namespace

std::map<int64_t, StoredFillet> pg_fillets(PgConnection& db, const std::string& server_id,
                                           const std::vector<int64_t>& uids) {
  std::map<int64_t, StoredFillet> out;
  if (uids.empty()) return out;
  const std::string ids = id_array(uids);
  const PgRows f = db.exec(
      "SELECT uid, lane, lane_fillet, first_encoder, rows, decision, reason, calibration_id, "
      "beta0, beta1, beta2, resid_mean_dn, resid_std_dn, belt_y0_mm, decided_ns FROM fillets "
      "WHERE server_id = $1 AND uid = ANY($2::bigint[])",
      {server_id, ids});
  for (int i = 0; i < f.rows(); ++i) {
    StoredFillet g;
    g.uid = f.i64(i, 0), g.lane = int(f.i64(i, 1)), g.lane_fillet = f.i64(i, 2);
    g.first_encoder = f.i64(i, 3), g.rows = int(f.i64(i, 4)), g.decision = f.str(i, 5);
    g.reason = f.str(i, 6), g.calibration_id = f.str(i, 7), g.beta0 = f.dbl(i, 8);
    g.beta1 = f.dbl(i, 9), g.beta2 = f.dbl(i, 10), g.resid_mean_dn = f.dbl(i, 11);
    g.resid_std_dn = f.dbl(i, 12), g.belt_y0_mm = f.dbl(i, 13), g.decided_ns = f.i64(i, 14);
    out[g.uid] = g;
  }
  const PgRows q = db.exec(
      "SELECT fillet_uid, kind, x_mm, y_mm, area_mm2, peak_z, attenuation_mm2, meat_mm, row0, "
      "row1, col0, col1, bone_mg FROM fragments WHERE server_id = $1 AND fillet_uid = "
      "ANY($2::bigint[]) ORDER BY fillet_uid, idx",
      {server_id, ids});
  for (int k = 0; k < q.rows(); ++k) {
    auto it = out.find(q.i64(k, 0));
    if (it == out.end()) continue;  // a fragment without its fillet: the chain check says so
    it->second.fragments.push_back({q.str(k, 1), q.dbl(k, 2), q.dbl(k, 3), q.dbl(k, 4), q.dbl(k, 5),
                                    q.dbl(k, 6), q.dbl(k, 7), int(q.i64(k, 8)), int(q.i64(k, 9)),
                                    int(q.i64(k, 10)), int(q.i64(k, 11)), q.dbl(k, 12)});
  }
  return out;
}

std::map<int64_t, AuditEntry> pg_audit(PgConnection& db, const std::string& server_id,
                                       const std::vector<int64_t>& rows) {
  std::map<int64_t, AuditEntry> out;
  if (rows.empty()) return out;
  const PgRows a = db.exec(
      "SELECT row_id, ts_ns, who, what, detail FROM audit WHERE server_id = $1 AND row_id = "
      "ANY($2::bigint[])",
      {server_id, id_array(rows)});
  for (int i = 0; i < a.rows(); ++i)
    out[a.i64(i, 0)] = {a.i64(i, 1), a.str(i, 2), a.str(i, 3), a.str(i, 4)};
  return out;
}

}  // namespace rangex
