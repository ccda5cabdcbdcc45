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
  // Lines the server handed back (not taken): sent again after a reconnect, in order.
  std::deque<InFlight> handed_back;
  bool holding = false;            // a line was handed back: this stream sends no more
  std::map<int, int64_t> settled;  // by lane, from the last credit query's answer
  uint64_t epoch = 0;              // the server's, from its last answer
  int credit = 1 << 20;
  bool broken = false;         // the current stream ended
  bool query_pending = false;  // a credit query awaits its answer
  uint64_t query_sequence = 0;
  Clock::time_point progress = Clock::now();
  uint64_t acked_on_stream = 0;     // lines the current stream got acknowledged
  uint64_t answered_on_stream = 0;  // credit queries the current stream got answered
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

// Asks the server for its credit (and each lane's settled count), with sh.mu held by `lock`;
// the answer is taken by the reader. False when the stream would not take the query.
template <class Stream>
bool ask_credit(Stream& stream, Shared& sh, uint64_t& seq, std::unique_lock<std::mutex>& lock) {
  pb::StreamLinesRequest query;
  query.set_sequence(seq++);
  query.set_credit_query(true);
  sh.query_pending = true;
  sh.query_sequence = query.sequence();
  lock.unlock();
  const bool open = stream.Write(query);  // no lock held: the reader must keep taking answers
  lock.lock();
  return open;
}

bool first_sent(const InFlight& a, const InFlight& b) {
  return a.req->sequence() < b.req->sequence();
}

void tell(const FeedOptions& opt, const std::string& m) {
  if (opt.log) opt.log(m);
}

// One answer of the server, with sh.mu held: the credit, the answer to a credit query, or the
// outcome of the oldest unacknowledged line (accepted, handed back, or refused).
void take_answer(const pb::StreamLinesResponse& r, Shared& sh, FeedReport& rep,
                 std::map<std::string, int>& told, const FeedOptions& opt) {
  sh.credit = r.credit();
  sh.epoch = r.server_epoch();
  sh.progress = Clock::now();
  if (sh.query_pending && r.sequence() == sh.query_sequence) {
    sh.query_pending = false;
    ++sh.answered_on_stream;
    for (const pb::LaneProgress& p : r.lanes())
      if (p.has_settled_encoder()) sh.settled[p.lane()] = p.settled_encoder();
    return;
  }
  if (sh.unacked.empty() || sh.unacked.front().req->sequence() != r.sequence()) return;
  InFlight line = std::move(sh.unacked.front());
  sh.unacked.pop_front();
  const std::string& code = r.error().code();
  if (r.accepted() || (line.resent && code == "DUPLICATE_LINE")) {
    if (!line.acked) ++rep.accepted;
    if (line.resent && code == "DUPLICATE_LINE") ++rep.duplicates;
    line.acked = true;
    ++sh.acked_on_stream;
    // Before the lane has a durable count nothing of it is durable: all kept.
    if (opt.keep_until_durable)
      retain(sh.retained, std::move(line),
             r.has_durable_encoder() ? r.durable_encoder() : INT64_MIN);
  } else if (code == "SHUTTING_DOWN" || code == "STORE_UNAVAILABLE") {
    // Not taken, not lost: kept, and sent again in order once a server can take it.
    ++rep.handed_back;
    if (told[code]++ < 1)
      tell(opt,
           "lines handed back (" + code + ": " + r.error().message() + "); they are sent again");
    line.resent = true;
    sh.handed_back.push_back(std::move(line));
    sh.holding = true;
  } else {
    ++rep.refused[code];
    if (told[code]++ < 3)
      tell(opt, "line " + std::to_string(r.sequence()) + " refused: " + code + ": " +
                    r.error().message());
  }
}

// Without an answer for reconnect_for_s (a server that does not come back: a call that waits
// for it would wait for ever, its opening included), the stream is cancelled and the feed
// gives up, naming what is not settled. `opening` and `over` are read under sh.mu.
std::thread watch_stream(Shared& sh, grpc::ClientContext& ctx, const bool& opening,
                         const bool& over, double reconnect_for_s) {
  return std::thread([&sh, &ctx, &opening, &over, reconnect_for_s] {
    std::unique_lock<std::mutex> lock(sh.mu);
    while (!over) {
      sh.cv.wait_for(lock, std::chrono::milliseconds(200));
      const bool waiting = opening || !sh.unacked.empty() || sh.query_pending;  // an answer
      if (!over && waiting &&
          Clock::now() - sh.progress > std::chrono::duration<double>(reconnect_for_s)) {
        lock.unlock();
        ctx.TryCancel();
        return;
      }
    }
  });
}

// After the first answer of a new stream, with sh.mu held: what this stream resends before
// new lines, in the order first sent. Another server than the one that acknowledged the
// retained lines (rangexd restarted) lacks what it had not made durable: those go too.
void gather_resends(Shared& sh, std::deque<InFlight>& again, uint64_t& known_epoch) {
  if (sh.epoch != known_epoch && known_epoch != 0) {
    for (auto& [lane, kept] : sh.retained)
      for (InFlight& f : kept) again.push_back(std::move(f));
    sh.retained.clear();
  }
  if (!sh.broken) known_epoch = sh.epoch;
  for (InFlight& f : sh.unacked) again.push_back(std::move(f));
  sh.unacked.clear();
  for (InFlight& f : sh.handed_back) again.push_back(std::move(f));
  sh.handed_back.clear();
  std::sort(again.begin(), again.end(), first_sent);
}

// After a stream ended, with sh.mu held: what it did not get to resend waits for the next,
// with what it left unacknowledged and what was handed back.
void keep_for_next_stream(Shared& sh, std::deque<InFlight>& again) {
  for (InFlight& f : again) sh.unacked.push_back(std::move(f));
  again.clear();
  for (InFlight& f : sh.handed_back) sh.unacked.push_back(std::move(f));
  sh.handed_back.clear();
  std::sort(sh.unacked.begin(), sh.unacked.end(), first_sent);
}

// The wait before a credit query that no line carries: longer each time, spread so that the
// streams of a plant do not all ask at the same moment.
struct Probe {
  static constexpr std::chrono::milliseconds kFirst{50};
  std::chrono::milliseconds wait = kFirst;
  std::minstd_rand jitter;
};

// Flow control: at most `window` lines unacknowledged, and no more than the credit of the
// last answer (this stream's share of the server's queue, counted after that line: the
// lines sent since will take from it). With no credit and nothing outstanding, ask for the
// credit again after a while, longer each time: never with a line, which a full queue would
// drop. False when this stream sends no more (it ended, lines were handed back, or `open`
// was cleared by a query it would not take).
template <class Stream>
bool wait_for_room(Stream& stream, Shared& sh, int window, uint64_t& seq, Probe& probe,
                   bool& open) {
  std::unique_lock<std::mutex> lock(sh.mu);
  while (true) {
    sh.cv.wait(lock, [&] {
      const int limit = std::min(window, std::max(sh.credit, 0));
      return sh.broken || sh.holding ||
             (!sh.query_pending && (int(sh.unacked.size()) < limit || sh.unacked.empty()));
    });
    if (sh.broken || sh.holding || int(sh.unacked.size()) < std::min(window, sh.credit)) break;
    // Spread over half to one and a half times the wait.
    lock.unlock();
    std::this_thread::sleep_for(probe.wait / 2 + probe.wait * (probe.jitter() % 1000) / 1000);
    probe.wait = std::min(probe.wait * 2, std::chrono::milliseconds(1000));
    lock.lock();
    open = ask_credit(stream, sh, seq, lock);
    if (!open) break;
  }
  if (sh.broken || sh.holding || !open) return false;
  probe.wait = Probe::kFirst;
  return true;
}

// After the last line: credit queries until every lane fed is settled past its last line
// (true), the stream ends or hands lines back, or settle_for_s has passed since the first
// call (false). The answers' lane progress is taken by the reader.
template <class Stream>
bool wait_settled_on(Stream& stream, Shared& sh, uint64_t& seq,
                     const std::map<int, int64_t>& last_sent, Clock::time_point& start,
                     double settle_for_s) {
  if (start == Clock::time_point::max()) start = Clock::now();
  std::unique_lock<std::mutex> lock(sh.mu);
  sh.cv.wait(lock, [&] { return sh.broken || sh.holding || sh.unacked.empty(); });
  while (true) {
    // An answer that said so counts though the stream ended right after it.
    bool all = true;
    for (const auto& [lane, last] : last_sent) {
      const auto it = sh.settled.find(lane);
      all = all && it != sh.settled.end() && it->second >= last;
    }
    if (all) return true;
    if (sh.broken || sh.holding) return false;
    if (Clock::now() - start > std::chrono::duration<double>(settle_for_s)) return false;
    if (!ask_credit(stream, sh, seq, lock)) return false;
    sh.cv.wait(lock, [&] { return !sh.query_pending || sh.broken; });
    lock.unlock();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    lock.lock();
  }
}

// What is not known to be in the store: the kept lines above each lane's last settled count
// (or every line of a lane never reported), as each lane's (first, last) count.
std::map<int, std::pair<int64_t, int64_t>> unsettled_counts(
    const Shared& sh, const std::map<int, int64_t>& last_sent) {
  std::map<int, std::pair<int64_t, int64_t>> out;
  for (const auto& [lane, last] : last_sent) {
    const auto it = sh.settled.find(lane);
    if (it != sh.settled.end() && it->second >= last) continue;
    int64_t first = last;
    auto lower = [&](const std::deque<InFlight>& d) {
      for (const InFlight& f : d)
        if (f.req->line().lane() == lane) first = std::min(first, f.req->line().encoder());
    };
    if (auto k = sh.retained.find(lane); k != sh.retained.end()) lower(k->second);
    lower(sh.unacked);
    if (it != sh.settled.end()) first = std::max(first, it->second + 1);
    out[lane] = {first, last};
  }
  return out;
}

// What one feed carries from stream to stream.
struct FeedState {
  int64_t next = 0;  // the next new line: n = next / lanes, lane = next % lanes
  uint64_t seq = 0;
  std::deque<InFlight> again;        // to resend on this stream, in first-sent order
  uint64_t known_epoch = 0;          // of the server that acknowledged what is retained
  std::map<int, int64_t> last_sent;  // by lane
  bool settled_all = false;
  Clock::time_point settle_start = Clock::time_point::max();
  static constexpr std::chrono::milliseconds kFirstBackoff{100};
  std::chrono::milliseconds backoff = kFirstBackoff;
};

// A new stream starts with nothing outstanding on it; `opening` is read by its watch.
void begin_stream(Shared& sh, bool& opening) {
  std::lock_guard<std::mutex> lock(sh.mu);
  opening = false;
  sh.broken = false;
  sh.holding = false;
  sh.query_pending = false;
  sh.acked_on_stream = 0;
  sh.answered_on_stream = 0;
}

// The stream's reader: every answer taken under sh.mu until the stream ends.
template <class Stream>
std::thread read_answers(Stream& stream, Shared& sh, FeedReport& rep,
                         std::map<std::string, int>& told, const FeedOptions& opt) {
  return std::thread([&stream, &sh, &rep, &told, &opt] {
    pb::StreamLinesResponse r;
    while (stream.Read(&r)) {
      std::lock_guard<std::mutex> lock(sh.mu);
      take_answer(r, sh, rep, told, opt);
      sh.cv.notify_all();
    }
    std::lock_guard<std::mutex> lock(sh.mu);
    sh.broken = true;
    sh.cv.notify_all();
  });
}

// First a credit query: its answer tells whether this is the server that had our lines, and
// so what this stream resends. False when the stream would not take the query.
template <class Stream>
bool first_answer(Stream& stream, Shared& sh, FeedState& st) {
  std::unique_lock<std::mutex> lock(sh.mu);
  const bool open = ask_credit(stream, sh, st.seq, lock);
  if (open) sh.cv.wait(lock, [&] { return !sh.query_pending || sh.broken; });
  gather_resends(sh, st.again, st.known_epoch);
  return open;
}

// The next line to send, counted as outstanding: a resend first, else line n of lane li.
std::shared_ptr<const pb::StreamLinesRequest> next_request(LineSource& source, int li, int64_t n,
                                                           Shared& sh, FeedState& st,
                                                           FeedReport& rep) {
  st.settle_start = Clock::time_point::max();  // the wait counts from the last line
  if (!st.again.empty()) {                     // a resend, under the same flow control as new lines
    InFlight f = std::move(st.again.front());
    st.again.pop_front();
    f.resent = true;
    std::shared_ptr<const pb::StreamLinesRequest> out = f.req;
    std::lock_guard<std::mutex> lock(sh.mu);
    sh.unacked.push_back(std::move(f));
    ++rep.resent;
    return out;
  }
  auto req = std::make_shared<pb::StreamLinesRequest>();
  req->set_sequence(st.seq++);
  source.line(li, n, *req->mutable_line());
  st.last_sent[req->line().lane()] = req->line().encoder();
  std::lock_guard<std::mutex> lock(sh.mu);
  sh.unacked.push_back({req, false});
  ++st.next;
  ++rep.sent;
  return req;
}

// What this stream resends, then the lines not yet sent, paced and under flow control, until
// all are sent or the stream sends no more (it ended, or lines were handed back). Returns
// whether the stream is still open for writing: one that holds handed-back lines is closed
// by WritesDone, so that the server ends it.
template <class Stream>
bool send_lines(Stream& stream, LineSource& source, int64_t total, Clock::time_point t0, Shared& sh,
                FeedState& st, Probe& probe, FeedReport& rep, const FeedOptions& opt) {
  const int64_t lanes = int64_t(source.lanes().size());
  bool open = true;
  while (open && (!st.again.empty() || st.next < total)) {
    const int64_t n = st.next / lanes;
    const int li = int(st.next % lanes);
    if (st.again.empty() && opt.rate > 0 && li == 0)  // pace: line n of every lane at n / rate s
      std::this_thread::sleep_until(t0 + std::chrono::duration<double>(double(n) / opt.rate));
    if (!wait_for_room(stream, sh, opt.window, st.seq, probe, open)) break;
    const auto out = next_request(source, li, n, sh, st, rep);
    open = stream.Write(*out);  // no lock held: the reader must keep taking acks
  }
  return open;
}

// After a stream ended, with its reader and watch joined: whether the feed is over (every line
// acknowledged, and settled or no longer waited for). What is left waits for the next stream.
bool feed_over(Shared& sh, FeedState& st, int64_t total, const FeedOptions& opt) {
  std::lock_guard<std::mutex> lock(sh.mu);
  keep_for_next_stream(sh, st.again);
  return st.next >= total && sh.unacked.empty() &&
         (st.settled_all || opt.settle_for_s <= 0 ||
          Clock::now() - st.settle_start > std::chrono::duration<double>(opt.settle_for_s));
}

// The wait before the next stream, said in the log.
void wait_to_reconnect(const Shared& sh, FeedState& st, FeedReport& rep, const FeedOptions& opt) {
  ++rep.reconnects;
  // A stream that got lines acknowledged, or (waiting to be settled, with no lines to
  // send) its queries answered and nothing handed back, was a working connection that
  // ended (a server that recycles connections, a restart): the next waits the first step
  // again, as gRPC's own connection backoff does once connected. Only streams that take
  // nothing (a server handing lines back, or one that fails at once) wait longer each time.
  if (sh.acked_on_stream > 0 || (sh.answered_on_stream > 0 && !sh.holding))
    st.backoff = FeedState::kFirstBackoff;
  rep.longest_backoff_ms = std::max<uint64_t>(rep.longest_backoff_ms, uint64_t(st.backoff.count()));
  size_t kept = 0;
  for (const auto& [lane, k] : sh.retained) kept += k.size();
  tell(opt, "stream ended (" + (rep.status.ok() ? std::string("OK") : rep.status.error_message()) +
                "); reconnecting and resending " + std::to_string(sh.unacked.size()) +
                " unacknowledged lines and " + std::to_string(kept) + " not yet durable");
  std::this_thread::sleep_for(st.backoff);
  st.backoff = std::min(st.backoff * 2, std::chrono::milliseconds(2000));
}

}  // namespace

FeedReport Feeder::run(LineSource& source) {
  FeedReport rep;
  Shared sh;
  std::map<std::string, int> told;
  auto stub = pb::IngestService::NewStub(channel_);
  const int64_t total = source.lines() * int64_t(source.lanes().size());
  const auto t0 = Clock::now();
  FeedState st;
  Probe probe{Probe::kFirst, std::minstd_rand(uint32_t(reinterpret_cast<uintptr_t>(&sh)))};

  while (true) {
    grpc::ClientContext ctx;
    ctx.set_wait_for_ready(true);  // a reconnect waits for the server to be back
    bool stream_over = false, opening = true;
    std::thread guard = watch_stream(sh, ctx, opening, stream_over, opt_.reconnect_for_s);
    auto stream = stub->StreamLines(&ctx);
    begin_stream(sh, opening);
    std::thread reader = read_answers(*stream, sh, rep, told, opt_);
    bool open = first_answer(*stream, sh, st);
    if (open) open = send_lines(*stream, source, total, t0, sh, st, probe, rep, opt_);
    // Every line sent: wait for them all to be settled in the store (a server that hands
    // lines back, or goes, sends this stream round again).
    if (open && st.next >= total && st.again.empty() && opt_.settle_for_s > 0 && !st.settled_all)
      st.settled_all =
          wait_settled_on(*stream, sh, st.seq, st.last_sent, st.settle_start, opt_.settle_for_s);
    if (open) stream->WritesDone();
    reader.join();
    {
      std::lock_guard<std::mutex> lock(sh.mu);
      stream_over = true;
    }
    sh.cv.notify_all();
    guard.join();
    rep.status = stream->Finish();
    if (feed_over(sh, st, total, opt_) && (rep.status.ok() || st.settled_all)) {
      // Every outcome is stored: a cut of the last stream after that (a server recycling
      // its connections) is not the feed's failure.
      if (st.settled_all && !rep.status.ok()) {
        tell(opt_, "the last stream ended (" + rep.status.error_message() +
                       ") after every outcome was stored");
        rep.status = grpc::Status::OK;
      }
      break;
    }
    if (!worth_reconnecting(rep.status) && !rep.status.ok()) break;
    if (Clock::now() - sh.progress > std::chrono::duration<double>(opt_.reconnect_for_s)) {
      tell(opt_, "no progress for " + std::to_string(int(opt_.reconnect_for_s)) + " s; giving up");
      break;
    }
    wait_to_reconnect(sh, st, rep, opt_);
  }
  rep.settled = st.settled_all || opt_.settle_for_s <= 0;
  if (!st.settled_all && opt_.settle_for_s > 0) rep.unsettled = unsettled_counts(sh, st.last_sent);
  rep.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return rep;
}

}  // namespace rangex
