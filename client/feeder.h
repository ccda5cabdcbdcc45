// A feeder as a line's cameras would run it: streams lines to rangexd, follows the server's
// credit (a line sent into a full queue would be dropped), keeps a window of lines not yet
// acknowledged, and after a dropped connection reconnects and resends from the last
// acknowledged line. The server answers a resent line it already has DUPLICATE_LINE; the
// feeder counts that as accepted (no second decision is made). Acknowledged lines are kept
// until the server says their outcome is durable (StreamLinesResponse.durable_encoder) and
// are resent too: a server that crashed rebuilds from them what it had not stored. Lines the
// server hands back (SHUTTING_DOWN, STORE_UNAVAILABLE) are sent again, in order, to the next
// server or once the store recovers. At the end it waits until every lane it fed is settled
// (each line's outcome in the store), or says which counts are not.
#pragma once
#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "channel.h"
#include "line_source.h"

namespace rangex {

struct FeedOptions {
  int window = 256;             // lines in flight at most
  double rate = 0;              // lines/s per lane; 0: as fast as the server takes them
  double reconnect_for_s = 60;  // without progress this long, give up
  // Keep acknowledged lines until the server says they are durable, to resend them to a
  // server that restarted. Off only where the feeder shares the server's process and its
  // memory would be counted as the server's (bench-server, soak).
  bool keep_until_durable = true;
  // At the end of the lines, wait up to this long for every lane fed to be settled past its
  // last line (0: return once every line is acknowledged).
  double settle_for_s = 90;
  // Told about refused lines (first few of each code, at most), and about reconnects.
  std::function<void(const std::string&)> log;
};

struct FeedReport {
  uint64_t sent = 0;      // distinct lines
  uint64_t accepted = 0;  // resent lines the server already had included
  uint64_t resent = 0, reconnects = 0;
  uint64_t longest_backoff_ms = 0;          // the longest wait before a reconnect
  uint64_t duplicates = 0;                  // resent lines the server answered it already had
  std::map<std::string, uint64_t> refused;  // by code, lost (handed-back lines are not)
  uint64_t handed_back = 0;                 // refusals of lines sent again later
  // With settle_for_s: whether every lane fed was settled past its last line, and if not,
  // the counts of each lane (first, last) not known to be settled.
  bool settled = false;
  std::map<int, std::pair<int64_t, int64_t>> unsettled;
  grpc::Status status;  // of the last stream (OK when all went through)
  double seconds = 0;
  uint64_t refused_total() const;
};

class Feeder {
 public:
  Feeder(std::shared_ptr<grpc::Channel> channel, FeedOptions opt);
  // Sends every line of `source` (line n of every lane before line n + 1), returns when all
  // are acknowledged or the connection cannot be had back within reconnect_for_s.
  FeedReport run(LineSource& source);

 private:
  std::shared_ptr<grpc::Channel> channel_;
  FeedOptions opt_;
};

}  // namespace rangex
