#include "plantdb/lane_handover.h"

#include "core/error.h"
#include "plantdb/pg_connection.h"

namespace rangex {

std::string LaneHandover::detail() const {
  return join("lane ", lane, " continues from server ", from_server, ": its fillet ",
              last_lane_fillet, " (uid ", uid, ", link ", seq, " ", hash,
              ") was the lane's last; numbering goes on at ", last_lane_fillet + 1);
}

std::vector<LaneHandover> lane_handovers(PgConnection& db, const std::string& server_id,
                                         const std::vector<int>& lanes) {
  std::vector<LaneHandover> out;
  for (int lane : lanes) {
    const PgRows r = db.exec(
        "SELECT f.server_id, f.lane_fillet, f.first_encoder + f.rows - 1, f.uid, l.seq, l.hash "
        "FROM fillets f LEFT JOIN ledger l ON l.server_id = f.server_id AND l.kind = 'fillet' "
        "AND l.ref = f.uid WHERE f.lane = $1::int ORDER BY f.decided_ns DESC, f.lane_fillet "
        "DESC LIMIT 1",
        {std::to_string(lane)});
    if (r.rows() == 0 || r.str(0, 0) == server_id) continue;
    out.push_back(
        {lane, r.str(0, 0), r.i64(0, 1), r.i64(0, 2), r.i64(0, 3), r.i64(0, 4), r.str(0, 5)});
  }
  return out;
}

}  // namespace rangex
