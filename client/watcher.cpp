#include "watcher.h"

#include <algorithm>
#include <thread>

#include "channel.h"
#include "rangex/v1/rangex.grpc.pb.h"

namespace rangex {

namespace pb = rangex::v1;
using Clock = std::chrono::steady_clock;

namespace {
// A stream open this long, or one that delivered a decision, counts as had: a refusal at once
// (the server's subscriptions full) does not hold off giving up.
constexpr auto kStreamHad = std::chrono::seconds(1);
constexpr auto kFirstBackoff = std::chrono::milliseconds(200);
constexpr auto kLongestBackoff = std::chrono::milliseconds(2000);
constexpr int kFillPage = 1000;

std::string said(const grpc::Status& s) {
  return "code " + std::to_string(int(s.error_code())) +
         (s.error_message().empty() ? "" : ": " + s.error_message());
}
}  // namespace

struct Watcher::State {
  bool known = false;    // since_ns and storage are the server's
  int64_t since_ns = 0;  // the server's clock when the watch began: fills start there
  int64_t last_uid = 0;  // the store's last decision this watch has passed (shown or not wanted)
  std::string storage;   // the server's store: another one shares no uids with this one
  bool done = false;     // count reached
  grpc::Status status;   // of the last call that failed
};

Watcher::Watcher(std::shared_ptr<grpc::Channel> channel, WatchOptions opt)
    : channel_(std::move(channel)), opt_(std::move(opt)) {}

bool Watcher::wanted(const pb::FilletResult& f) const {
  const auto& lanes = opt_.filter.lanes();
  const auto& decisions = opt_.filter.decisions();
  return (lanes.empty() || std::find(lanes.begin(), lanes.end(), f.lane()) != lanes.end()) &&
         (decisions.empty() ||
          std::find(decisions.begin(), decisions.end(), int(f.decision())) != decisions.end());
}

bool Watcher::show(State& st, const pb::FilletResult& f, WatchReport& rep) {
  st.last_uid = std::max(st.last_uid, f.uid());
  if (!wanted(f)) return false;
  if (opt_.show) opt_.show(f);
  ++rep.shown;
  if (opt_.count && rep.shown >= opt_.count) st.done = true;
  return true;
}

// The server's clock and store: where a fill starts, and whether the store is the one whose
// uids this watch has followed.
bool Watcher::begin(State& st) {
  auto stub = pb::ControlService::NewStub(channel_);
  // Waits for the connection: a call that fails at once while the channel is between attempts
  // had the watch reconnect 7 s after the server was back, this 1.6 s.
  UnaryCall c;
  c.set_wait_for_ready(true);
  if (opt_.until && *opt_.until < c.deadline()) c.set_deadline(*opt_.until);
  pb::GetServerInfoResponse info;
  st.status = stub->GetServerInfo(&c, {}, &info);
  if (!st.status.ok()) return false;
  // A server without the field (before now_ns) is read on this machine's clock.
  const int64_t now = info.now_ns() > 0 ? info.now_ns()
                                        : std::chrono::duration_cast<std::chrono::nanoseconds>(
                                              std::chrono::system_clock::now().time_since_epoch())
                                              .count();
  if (st.known && info.storage() != st.storage && opt_.log)
    opt_.log("the server now keeps another store (" + info.storage() + ", was " + st.storage +
             "): decisions from here on");
  if (!st.known || info.storage() != st.storage) {
    st.known = true;
    st.since_ns = now;
    st.last_uid = 0;
    st.storage = info.storage();
  }
  return true;
}

// Shows what the store decided after last_uid and below below_uid, in the store's order.
bool Watcher::fill(State& st, int64_t below_uid, WatchReport& rep) {
  auto stub = pb::ResultsService::NewStub(channel_);
  pb::ListFilletsRequest q;
  q.set_from_ns(st.since_ns);
  q.set_lane(opt_.filter.lanes_size() == 1 ? opt_.filter.lanes(0) : -1);
  q.set_page_size(kFillPage);
  if (st.last_uid > 0) q.set_page_token(std::to_string(st.last_uid));
  for (;;) {
    UnaryCall c;
    pb::ListFilletsResponse page;
    st.status = stub->ListFillets(&c, q, &page);
    if (!st.status.ok()) return false;
    for (const pb::FilletResult& f : page.fillets()) {
      if (f.uid() >= below_uid || st.done) return true;
      if (show(st, f, rep)) ++rep.filled;
    }
    if (page.next_page_token().empty()) return true;
    q.set_page_token(page.next_page_token());
  }
}

WatchReport Watcher::run() {
  WatchReport rep;
  State st;
  auto stub = pb::ResultsService::NewStub(channel_);
  auto lost_at = Clock::now();
  auto backoff = std::chrono::milliseconds(kFirstBackoff);
  bool lost = false;      // a stream was had and ended: what it missed is in the store
  bool announced = true;  // the last loss of a stream that was had is followed by a word
  for (;;) {
    if (opt_.until && std::chrono::system_clock::now() >= *opt_.until) return rep;
    grpc::Status why;
    if (begin(st)) {
      grpc::ClientContext ctx;
      if (opt_.until) ctx.set_deadline(*opt_.until);
      const auto opened = Clock::now();
      auto reader = stub->SubscribeFillets(&ctx, opt_.filter);
      const uint64_t filled_before = rep.filled;
      // Decided while no stream was open; the stream may begin after this fill, so the first
      // decision it sends fills again up to itself.
      if (lost && fill(st, INT64_MAX, rep) && !announced) {
        announced = true;
        if (opt_.log)
          opt_.log("connected again; " + std::to_string(rep.filled - filled_before) +
                   " decided meanwhile, taken from the store");
      }
      bool gap = lost;
      bool had = false;
      pb::SubscribeFilletsResponse r;
      while (!st.done && reader->Read(&r)) {
        had = true;
        // A lag is decisions this stream skipped (it read too slowly): the store has them.
        if (gap || r.lagged()) fill(st, r.fillet().uid(), rep);
        gap = false;
        if (!st.done && r.fillet().uid() > st.last_uid) show(st, r.fillet(), rep);
      }
      if (st.done) {
        ctx.TryCancel();
        reader->Finish();
        return rep;
      }
      why = reader->Finish();
      if (opt_.until && std::chrono::system_clock::now() >= *opt_.until) return rep;
      if (had || Clock::now() - opened >= kStreamHad) {
        lost_at = Clock::now();
        backoff = kFirstBackoff;
        announced = false;
      }
      // A stream that ends well is a server that stopped: its next one has more.
      if (why.ok())
        why = grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server ended the stream");
      lost = true;
    } else {
      why = st.status;
    }
    if (!worth_reconnecting(why)) {
      rep.status = why;
      return rep;
    }
    const double away = std::chrono::duration<double>(Clock::now() - lost_at).count();
    if (opt_.reconnect_for_s <= 0 || away > opt_.reconnect_for_s) {
      rep.status = why;
      if (opt_.reconnect_for_s > 0 && opt_.log)
        opt_.log("no stream for " + std::to_string(int(away)) + " s; giving up (" + said(why) +
                 ")");
      return rep;
    }
    if (backoff == kFirstBackoff && opt_.log)
      opt_.log("stream lost (" + said(why) + "); connecting again");
    std::this_thread::sleep_for(backoff);
    backoff = std::min(backoff * 2, std::chrono::milliseconds(kLongestBackoff));
    ++rep.reconnects;
  }
}

}  // namespace rangex
