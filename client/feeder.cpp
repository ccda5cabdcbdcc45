#include "feeder.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <random>
#include <thread>

#include "rangex/v1/rangex.grpc.pb.h"

namespace rangex {

namespace pb = rangex::v1;
using Clock = std::chrono::steady_clock;

uint64_t FeedReport::refused_total() const {
  uint64_t n = 0;
  for (const auto& [code, k] : refused) n += k;
  return n;
}

Feeder::Feeder(std::shared_ptr<grpc::Channel> channel, FeedOptions opt)
    : channel_(std::move(channel)), opt_(std::move(opt)) {}

namespace {

bool retryable(const grpc::Status& s) {
  switch (s.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::CANCELLED:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::ABORTED:
      return true;
    default:
      return false;
  }
}

// Shared with the writer while it writes: the reader may drop its own reference as soon as
// the line is acknowledged.
struct InFlight {
  std::shared_ptr<const pb::StreamLinesRequest> req;
  bool resent = false;
  bool acked = false;  // counted as accepted already (a retained line sent again)
};

// What the writer and the reader of one feed share.
struct Shared {
  std::mutex mu;
  std::condition_variable cv;
  std::deque<InFlight> unacked;  // in sequence order
  // Acknowledged lines whose outcome the server has not yet made durable, by lane, in
  // order: resent after a reconnect with the unacknowledged ones, so that a server that
  // crashed rebuilds what it had not stored.
  std::map<int, std::deque<InFlight>> retained;
  uint64_t epoch = 0;  // the server's, from its last answer
  int credit = 1 << 20;
  bool broken = false;         // the current stream ended
  bool query_pending = false;  // a credit query awaits its answer
  uint64_t query_sequence = 0;
  Clock::time_point progress = Clock::now();
};

// Keeps an acknowledged line until its lane is durable past it, and forgets what is.
void retain(std::map<int, std::deque<InFlight>>& retained, InFlight&& line, int64_t durable) {
  const int lane = line.req->line().lane();
  const int64_t encoder = line.req->line().encoder();
  std::deque<InFlight>& kept = retained[lane];
  // Counts that went back (an encoder reset the server took): the older lines belong to a
  // count sequence that is over.
  if (!kept.empty() && encoder < kept.back().req->line().encoder()) kept.clear();
  if (encoder > durable) kept.push_back(std::move(line));
  while (!kept.empty() && kept.front().req->line().encoder() <= durable) kept.pop_front();
}

}  // namespace

FeedReport Feeder::run(LineSource& source) {
  FeedReport rep;
  Shared sh;
  auto say = [&](const std::string& m) {
    if (opt_.log) opt_.log(m);
  };
  std::map<std::string, int> told;
  auto stub = pb::IngestService::NewStub(channel_);
  const auto lanes = source.lanes();
  const int64_t total = source.lines() * int64_t(lanes.size());
  const auto t0 = Clock::now();
  int64_t next = 0;  // the next new line: n = next / lanes, lane = next % lanes
  uint64_t seq = 0;
  auto backoff = std::chrono::milliseconds(100);
  auto probe_wait = std::chrono::milliseconds(50);
  std::minstd_rand jitter(uint32_t(reinterpret_cast<uintptr_t>(&sh)));
  std::deque<InFlight> again;  // to resend on this stream, in first-sent order
  uint64_t known_epoch = 0;    // of the server that acknowledged what is retained

  while (true) {
    grpc::ClientContext ctx;
    ctx.set_wait_for_ready(true);  // a reconnect waits for the server to be back
    auto stream = stub->StreamLines(&ctx);
    {
      std::lock_guard<std::mutex> lock(sh.mu);
      sh.broken = false;
      sh.query_pending = false;
    }
    std::thread reader([&] {
      pb::StreamLinesResponse r;
      while (stream->Read(&r)) {
        std::lock_guard<std::mutex> lock(sh.mu);
        sh.credit = r.credit();
        sh.epoch = r.server_epoch();
        sh.progress = Clock::now();
        if (sh.query_pending && r.sequence() == sh.query_sequence) {
          sh.query_pending = false;
          sh.cv.notify_all();
          continue;
        }
        if (sh.unacked.empty() || sh.unacked.front().req->sequence() != r.sequence()) continue;
        InFlight line = std::move(sh.unacked.front());
        sh.unacked.pop_front();
        const std::string& code = r.error().code();
        if (r.accepted() || (line.resent && code == "DUPLICATE_LINE")) {
          if (!line.acked) ++rep.accepted;
          if (line.resent && code == "DUPLICATE_LINE") ++rep.duplicates;
          line.acked = true;
          if (opt_.keep_until_durable && r.has_durable_encoder())
            retain(sh.retained, std::move(line), r.durable_encoder());
        } else {
          ++rep.refused[code];
          if (told[code]++ < 3)
            say("line " + std::to_string(r.sequence()) + " refused: " + code + ": " +
                r.error().message());
        }
        sh.cv.notify_all();
      }
      std::lock_guard<std::mutex> lock(sh.mu);
      sh.broken = true;
      sh.cv.notify_all();
    });

    // First a credit query: its answer tells whether this is the server that had our
    // lines. Another one (rangexd restarted) lacks what it had not made durable: those are
    // resent with the unacknowledged lines, in the order first sent, before new lines; the
    // same one still has them.
    bool open = true;
    {
      pb::StreamLinesRequest query;
      query.set_sequence(seq++);
      query.set_credit_query(true);
      std::unique_lock<std::mutex> lock(sh.mu);
      sh.query_pending = true;
      sh.query_sequence = query.sequence();
      lock.unlock();
      open = stream->Write(query);
      lock.lock();
      if (open) sh.cv.wait(lock, [&] { return !sh.query_pending || sh.broken; });
      if (sh.epoch != known_epoch && known_epoch != 0) {
        for (auto& [lane, kept] : sh.retained)
          for (InFlight& f : kept) again.push_back(std::move(f));
        sh.retained.clear();
      }
      if (!sh.broken) known_epoch = sh.epoch;
      for (InFlight& f : sh.unacked) again.push_back(std::move(f));
      sh.unacked.clear();
      std::sort(again.begin(), again.end(), [](const InFlight& a, const InFlight& b) {
        return a.req->sequence() < b.req->sequence();
      });
    }
    while (open && (!again.empty() || next < total)) {
      const int64_t n = next / int64_t(lanes.size());
      const int li = int(next % int64_t(lanes.size()));
      if (again.empty() && opt_.rate > 0 && li == 0)  // pace: line n of every lane at n / rate s
        std::this_thread::sleep_until(t0 + std::chrono::duration<double>(double(n) / opt_.rate));
      std::shared_ptr<const pb::StreamLinesRequest> out;
      {
        // Flow control: at most `window` lines unacknowledged, and no more than the credit
        // of the last answer (this stream's share of the server's queue, counted after that
        // line: the lines sent since will take from it). With no credit and nothing
        // outstanding, ask for the credit again after a while, longer each time: never
        // with a line, which a full queue would drop.
        std::unique_lock<std::mutex> lock(sh.mu);
        while (true) {
          sh.cv.wait(lock, [&] {
            const int limit = std::min(opt_.window, std::max(sh.credit, 0));
            return sh.broken ||
                   (!sh.query_pending && (int(sh.unacked.size()) < limit || sh.unacked.empty()));
          });
          if (sh.broken || int(sh.unacked.size()) < std::min(opt_.window, sh.credit)) break;
          // Spread over half to one and a half times the wait, so that the streams of a
          // plant do not all ask at the same moment.
          lock.unlock();
          std::this_thread::sleep_for(probe_wait / 2 + probe_wait * (jitter() % 1000) / 1000);
          probe_wait = std::min(probe_wait * 2, std::chrono::milliseconds(1000));
          pb::StreamLinesRequest query;
          query.set_sequence(seq++);
          query.set_credit_query(true);
          lock.lock();
          sh.query_pending = true;
          sh.query_sequence = query.sequence();
          lock.unlock();
          open = stream->Write(query);
          lock.lock();
          if (!open) break;
        }
        if (sh.broken || !open) break;
        probe_wait = std::chrono::milliseconds(50);
      }
      if (!again.empty()) {  // a resend, under the same flow control as new lines
        InFlight f = std::move(again.front());
        again.pop_front();
        f.resent = true;
        out = f.req;
        std::lock_guard<std::mutex> lock(sh.mu);
        sh.unacked.push_back(std::move(f));
        ++rep.resent;
      } else {
        auto req = std::make_shared<pb::StreamLinesRequest>();
        req->set_sequence(seq++);
        source.line(li, n, *req->mutable_line());
        out = req;
        std::lock_guard<std::mutex> lock(sh.mu);
        sh.unacked.push_back({out, false});
        ++next;
        ++rep.sent;
      }
      open = stream->Write(*out);  // no lock held: the reader must keep taking acks
    }
    if (open) stream->WritesDone();
    reader.join();
    rep.status = stream->Finish();
    bool done;
    {
      // What this stream did not get to resend waits for the next, with what it left
      // unacknowledged.
      std::lock_guard<std::mutex> lock(sh.mu);
      for (InFlight& f : again) sh.unacked.push_back(std::move(f));
      again.clear();
      done = next >= total && sh.unacked.empty();
    }
    if (done && rep.status.ok()) break;
    if (!retryable(rep.status) && !rep.status.ok()) break;
    if (Clock::now() - sh.progress > std::chrono::duration<double>(opt_.reconnect_for_s)) {
      say("no progress for " + std::to_string(int(opt_.reconnect_for_s)) + " s; giving up");
      break;
    }
    ++rep.reconnects;
    size_t kept = 0;
    for (const auto& [lane, k] : sh.retained) kept += k.size();
    say("stream ended (" + (rep.status.ok() ? std::string("OK") : rep.status.error_message()) +
        "); reconnecting and resending " + std::to_string(sh.unacked.size()) +
        " unacknowledged lines and " + std::to_string(kept) + " not yet durable");
    std::this_thread::sleep_for(backoff);
    backoff = std::min(backoff * 2, std::chrono::milliseconds(2000));
  }
  rep.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return rep;
}

}  // namespace rangex
