// How a server's forwarding to the plant-wide database stands (plantdb/forwarder.h), as
// statistics, /metrics and the dashboard show it.
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

struct ForwarderStatus {
  std::string server_id, database;  // the id it forwards as; where (no password)
  bool connected = false;
  std::string state;       // forwarding | caught up | unreachable | refused
  std::string last_error;  // the last failure ("" once forwarding again)
  int64_t head_seq = 0, forwarded_seq = 0;
  int64_t lag_records = 0;        // chain links stored here and not yet in the database
  double lag_seconds = 0;         // age of the oldest of them
  int64_t links = 0, images = 0;  // forwarded by this process
  int64_t failures = 0;
};

}  // namespace rangex
