// A lane moved to this server (the plant file now names it here, after a hardware fault on
// the server that ran it) keeps one history: its fillet numbers go on from the last one the
// plant-wide database holds for it, a fillet already decided there is not decided again, and
// the first entry of this server's chain names the other server's link it continues from.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

class PgConnection;

struct LaneHandover {
  int lane = 0;
  std::string from_server;
  int64_t last_lane_fillet = 0;  // the lane's last fillet number there
  int64_t last_end = 0;          // the encoder count its last fillet ended at
  int64_t uid = 0, seq = 0;      // that fillet there, and its link in that server's chain
  std::string hash;

  // The audit entry's detail: which server, which fillet, which link.
  std::string detail() const;
};

// The lanes of `server_id` among `lanes` whose latest record in the database is another
// server's.
std::vector<LaneHandover> lane_handovers(PgConnection& db, const std::string& server_id,
                                         const std::vector<int>& lanes);

}  // namespace rangex
