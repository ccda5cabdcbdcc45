#include "service/streams.h"

#include <algorithm>
#include <chrono>
#include <deque>
#include <memory>
#include <mutex>

#include "core/error.h"
#include "rangex/v1/decision_names.h"
#include "service/engine.h"
#include "service/line_from_proto.h"
#include "service/pb_convert.h"
#include "service/results_hub.h"
#include "service/steady_ns.h"
#include "service/tsan_annotations.h"

namespace rangex {

namespace pb = rangex::v1;

namespace {

// Acknowledgements waiting to be written before reading pauses.
constexpr size_t kMaxPendingAcks = 256;

// A subscription with more results than this waiting for it has fallen behind: it may give
// way to a new one. One that keeps up has none waiting, or the one being written.
constexpr uint64_t kBehindResults = 16;

// gRPC runs a reactor's reactions after the handler that created it returned, and OnDone
// after every other reaction returned; it orders them with its own (uninstrumented)
// synchronisation. A Reaction at the top of each says so to ThreadSanitizer.
class Reaction {
 public:
  explicit Reaction(const void* reactor) : r_(reactor) { RANGEX_HAPPENS_AFTER(r_); }
  ~Reaction() { RANGEX_HAPPENS_BEFORE(r_); }
  Reaction(const Reaction&) = delete;
  Reaction& operator=(const Reaction&) = delete;

 private:
  const void* r_;
};

// On a full server: the stream with no request for longest gives way to a newcomer, if that
// is at least gives_way_s. Streams that feed are never cut for it. False when none gave way.
bool give_way_quietest(const std::vector<std::shared_ptr<IdleClosable>>& open,
                       const IngestBound& bound) {
  std::vector<std::pair<int64_t, IdleClosable*>> by_quiet;
  for (const auto& s : open) by_quiet.emplace_back(s->last_request_ns(), s.get());
  std::sort(by_quiet.begin(), by_quiet.end());
  const int64_t now = steady_ns(), quiet = int64_t(bound.gives_way_s * 1e9);
  const std::string why =
      join("no request for ", bound.gives_way_s, " s while the server held its ", bound.max_streams,
           " ingest streams (server.max_ingest_streams): closed for a new one; reconnect to feed");
  // Another newcomer may take the same one first: then the next quietest.
  for (const auto& [last, s] : by_quiet) {
    if (now - last < quiet) return false;
    if (s->close_if_idle(now, quiet, why)) return true;
  }
  return false;
}

// Owned by itself (self_) until OnDone; the idle sweep holds only a weak reference, so a
// sweep that races OnDone keeps the reactor alive until it returns.
class IngestStream final
    : public grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>,
      public IdleClosable {
 public:
  // nullptr when the server holds max_streams already and none of them gives way.
  static IngestStream* start(Engine& engine, StreamCounters& counters, const IngestBound& bound) {
    std::shared_ptr<IngestStream> s;
    std::vector<std::shared_ptr<IdleClosable>> open;
    {
      // Counted (the constructor) under the registry's lock: newcomers at the same time see
      // each other. A stream stops counting in OnDone.
      std::lock_guard<std::mutex> lock(counters.live_mu);
      if (counters.ingest < bound.max_streams) {
        s.reset(new IngestStream(engine, counters));
        counters.live.push_back(s);
      } else {
        for (const auto& w : counters.live)
          if (auto live = w.lock()) open.push_back(std::move(live));
      }
    }
    if (!s) {
      // Outside the registry's lock: Finish may run reactions of its own. The one that gave
      // way counts until its OnDone, so the server holds one more meanwhile.
      if (!give_way_quietest(open, bound)) return nullptr;
      std::lock_guard<std::mutex> lock(counters.live_mu);
      s.reset(new IngestStream(engine, counters));
      counters.live.push_back(s);
    }
    std::lock_guard<std::mutex> lock(s->mu_);
    s->self_ = s;
    s->reading_ = true;
    s->StartRead(&s->req_);
    RANGEX_HAPPENS_BEFORE(s.get());  // gRPC runs the reactions after the handler returns
    return s.get();
  }

  bool close_if_idle(int64_t now_ns, int64_t idle_ns, const std::string& why) override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      // A stream writing acks is not idle; one already ending is left to end.
      if (finished_ || broken_ || writing_ || now_ns - last_ns_ < idle_ns) return false;
      broken_ = expired_ = finished_ = true;
    }
    // The pending read then completes with ok = false; nothing else is started.
    Finish(grpc::Status(grpc::StatusCode::UNAVAILABLE, why));
    return true;
  }

  int64_t last_request_ns() override {
    std::lock_guard<std::mutex> lock(mu_);
    return last_ns_;
  }

  void OnReadDone(bool ok) override {
    // The read slot stays taken (reading_) until the line is handled, so that no new read
    // overwrites req_ and lines of one stream reach the engine in the order they came. The
    // empty critical section orders this reaction after the one that started the read.
    Reaction reaction(this);
    bool expired;
    {
      std::lock_guard<std::mutex> lock(mu_);
      last_ns_ = steady_ns();
      expired = expired_;
    }
    pb::StreamLinesResponse ack;
    // No lock held: the engine is another module. A line that came as the stream was closed
    // for idleness is not submitted: unacknowledged, its feeder resends it.
    if (ok && !expired) ack = handle(req_);
    bool finish;
    {
      std::lock_guard<std::mutex> lock(mu_);
      reading_ = false;
      if (!ok) {
        reads_done_ = true;
      } else if (!broken_) {
        acks_.push_back(std::move(ack));
        if (!writing_) {
          writing_ = true;
          StartWrite(&acks_.front());
        }
      }
      read_more();
      finish = ready_to_finish();
    }
    if (finish) Finish(grpc::Status::OK);
  }

  void OnWriteDone(bool ok) override {
    Reaction reaction(this);
    bool finish;
    {
      std::lock_guard<std::mutex> lock(mu_);
      writing_ = false;
      acks_.pop_front();
      if (!ok) {  // the client is gone: nothing of it is pending
        broken_ = true;
        acks_.clear();
      } else if (!acks_.empty()) {
        writing_ = true;
        StartWrite(&acks_.front());
      }
      read_more();
      finish = ready_to_finish();
    }
    if (finish) Finish(grpc::Status::OK);
  }

  void OnCancel() override {
    Reaction reaction(this);
    bool finish;
    {
      std::lock_guard<std::mutex> lock(mu_);
      broken_ = true;
      finish = ready_to_finish();
    }
    if (finish) Finish(grpc::Status::CANCELLED);
  }

  void OnDone() override {
    RANGEX_HAPPENS_AFTER(this);  // every reaction has returned
    std::shared_ptr<IngestStream> last;
    {
      std::lock_guard<std::mutex> lock(mu_);
      last = std::move(self_);  // freed when this returns, or when a sweep lets go of it
    }
    --counters_.ingest;
    if (fed_) --counters_.feeding;
  }

 private:
  IngestStream(Engine& engine, StreamCounters& counters) : engine_(engine), counters_(counters) {
    ++counters_.ingest;
  }
  pb::StreamLinesResponse handle(pb::StreamLinesRequest& req) {
    pb::StreamLinesResponse resp;
    resp.set_sequence(req.sequence());
    resp.set_server_epoch(engine_.epoch());
    Engine::Verdict v;
    if (!req.has_line() && req.credit_query()) {
      v.credit = engine_.free_places();  // a question, not a line: nothing is counted
      resp.set_credit(credit(v));
      for (const LaneProgress& p : engine_.progress()) {
        pb::LaneProgress* out = resp.add_lanes();
        out->set_lane(p.lane);
        if (p.durable != INT64_MIN) out->set_durable_encoder(p.durable);
        if (p.settled != INT64_MIN) out->set_settled_encoder(p.settled);
      }
      return resp;
    }
    if (!req.has_line()) {
      v = engine_.refuse_empty(req.sequence());
    } else {
      if (!fed_) ++counters_.feeding, fed_ = true;
      IncomingLine in = take_line(*req.mutable_line());
      in.queued_by = queued_;
      v = engine_.submit(std::move(in));
    }
    resp.set_accepted(v.accepted);
    resp.set_credit(credit(v));
    if (v.durable != INT64_MIN) resp.set_durable_encoder(v.durable);
    if (!v.accepted) {
      resp.mutable_error()->set_code(std::string(refusal_name(v.code)));
      resp.mutable_error()->set_message(v.message);
    }
    return resp;
  }
  int credit(const Engine::Verdict& v) const {
    // The queue is shared: each stream's credit is its quota (an equal share of the queue
    // among the streams that feed, this one included, and at least as many as the plant has
    // lanes, so that the first streams to connect do not take it all) less its own lines
    // still queued, and
    // never more than its equal share of the free places. A feeder that keeps its lines in
    // flight within its credit keeps queued + in flight within its quota; and since the
    // lines of streams that have closed stay queued after them, the share of the free
    // places keeps the streams still open from overrunning the queue together when they
    // all answer at once.
    // Streams that have sent no line take no share: 500 that sent nothing once cut a real
    // feeder's credit from 512 to 4.
    const int streams =
        std::max(counters_.feeding.load() + (fed_ ? 0 : 1), int(engine_.plant().lanes.size()));
    const int quota = int(engine_.options().queue_lines) / std::max(1, streams);
    const int share = v.credit / std::max(1, streams);
    return std::max(0, std::min(share, quota - queued_->load()));
  }
  void read_more() {
    if (!reading_ && !reads_done_ && !broken_ && acks_.size() < kMaxPendingAcks) {
      reading_ = true;
      StartRead(&req_);
    }
  }
  bool ready_to_finish() {
    if (finished_ || reading_ || writing_ || !(reads_done_ || broken_)) return false;
    finished_ = true;
    return true;
  }

  Engine& engine_;
  StreamCounters& counters_;
  std::shared_ptr<std::atomic<int>> queued_ = std::make_shared<std::atomic<int>>(0);
  std::mutex mu_;
  pb::StreamLinesRequest req_;
  std::deque<pb::StreamLinesResponse> acks_;  // front: being written
  bool reading_ = false, writing_ = false, reads_done_ = false, broken_ = false;
  bool finished_ = false;
  bool fed_ = false;      // a line came (the reading reaction's alone: reads are one at a time)
  bool expired_ = false;  // closed by the idle sweep
  int64_t last_ns_ = steady_ns();  // the last request (or the start)
  std::shared_ptr<IngestStream> self_;
};

// Owned by itself (self_) until OnDone; the hub's wake and the registry of subscriptions
// hold only weak references, so a wake or an eviction that races OnDone keeps the reactor
// alive until it returns.
class Subscription final : public grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>,
                           public Evictable,
                           public std::enable_shared_from_this<Subscription> {
 public:
  // Made under the registry's lock, started (subscribed to the hub) outside it.
  static std::shared_ptr<Subscription> make(ResultsHub& hub, StreamCounters& counters,
                                            grpc::CallbackServerContext* ctx) {
    return std::shared_ptr<Subscription>(new Subscription(hub, counters, ctx));
  }

  Subscription* start(const pb::SubscribeFilletsRequest& req) {
    std::set<int> lanes(req.lanes().begin(), req.lanes().end());
    std::set<std::string> decisions;
    for (int d : req.decisions()) decisions.insert(decision_name(pb::Decision(d)));
    std::weak_ptr<Subscription> weak = shared_from_this();
    auto sub = hub_.subscribe(std::move(lanes), std::move(decisions), 256, [weak] {
      if (auto p = weak.lock()) p->deliver();
    });
    {
      std::lock_guard<std::mutex> lock(mu_);
      sub_ = std::move(sub);
      self_ = shared_from_this();
    }
    RANGEX_HAPPENS_BEFORE(this);  // gRPC runs the reactions after the handler returns
    deliver();                    // results or a close that came before sub_ was set
    return this;
  }

  uint64_t backlog() override {
    std::shared_ptr<ResultsHub::Subscription> sub;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_ || evicted_) return 0;
      sub = sub_;
    }
    return sub ? hub_.backlog(sub) : 0;
  }

  // The call is cancelled (a client that stopped reading has a write pending that would
  // never end, and with it the stream) and then finished. Finish waits until TryCancel has
  // returned: until Finish, gRPC does not call OnDone, so the context is alive. No lock is
  // held across TryCancel, as gRPC may run this stream's reactions inside it.
  void give_way() override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (finished_ || evicted_) return;
      evicted_ = cancelling_ = true;
    }
    ctx_->TryCancel();
    {
      std::lock_guard<std::mutex> lock(mu_);
      cancelling_ = false;
    }
    deliver();
  }

  void OnWriteDone(bool ok) override {
    Reaction reaction(this);
    {
      std::lock_guard<std::mutex> lock(mu_);
      writing_ = false;
      if (!ok) cancelled_ = true;
    }
    deliver();
  }
  void OnCancel() override {
    Reaction reaction(this);
    {
      std::lock_guard<std::mutex> lock(mu_);
      cancelled_ = true;
    }
    deliver();
  }
  void OnDone() override {
    RANGEX_HAPPENS_AFTER(this);  // every reaction has returned
    std::shared_ptr<Subscription> last;
    {
      std::lock_guard<std::mutex> lock(mu_);
      finished_ = true;
      hub_.unsubscribe(sub_);
      last = std::move(self_);
    }
    --counters_.subscribers;
    // `last` may be the final reference: the reactor is deleted as this returns.
  }

 private:
  Subscription(ResultsHub& hub, StreamCounters& counters, grpc::CallbackServerContext* ctx)
      : hub_(hub), counters_(counters), ctx_(ctx) {
    ++counters_.subscribers;
  }

  void deliver() {
    Reaction reaction(this);  // also from the hub's wake: the same order applies
    grpc::Status end;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (writing_ || finished_ || cancelling_ || !sub_) return;
      StoredFillet f;
      uint64_t lagged = 0;
      if (evicted_) {
        end = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                           "this subscription fell behind and gave way to a new one (the "
                           "server holds server.max_subscriptions at once)");
      } else if (cancelled_) {
        end = grpc::Status::CANCELLED;
      } else if (hub_.take(sub_, f, lagged)) {
        resp_.Clear();
        fill(resp_.mutable_fillet(), f);
        resp_.set_lagged(lagged);
        writing_ = true;
        StartWrite(&resp_);
        return;
      } else if (!hub_.closed(sub_)) {
        return;
      }
      finished_ = true;  // closed and drained, or cancelled
    }
    Finish(end);
  }

  ResultsHub& hub_;
  StreamCounters& counters_;
  grpc::CallbackServerContext* const ctx_;
  std::mutex mu_;
  std::shared_ptr<ResultsHub::Subscription> sub_;
  std::shared_ptr<Subscription> self_;
  pb::SubscribeFilletsResponse resp_;
  bool writing_ = false, cancelled_ = false, finished_ = false;
  bool evicted_ = false;     // gave way to a new subscription
  bool cancelling_ = false;  // in give_way's TryCancel: not to be finished yet
};

}  // namespace

namespace {
// A stream refused before it starts (its caller may not open it): finished at once.
template <typename Base>
struct Refused final : Base {
  explicit Refused(const grpc::Status& s) {
    this->Finish(s);
    RANGEX_HAPPENS_BEFORE(this);  // gRPC runs OnDone after the handler returns
  }
  void OnDone() override {
    RANGEX_HAPPENS_AFTER(this);
    delete this;
  }
};
}  // namespace

grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>* refused_ingest_stream(
    const grpc::Status& status) {
  return new Refused<grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>>(
      status);
}

grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>* refused_subscription(
    const grpc::Status& status) {
  return new Refused<grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>>(status);
}

grpc::ServerBidiReactor<pb::StreamLinesRequest, pb::StreamLinesResponse>* new_ingest_stream(
    Engine& engine, StreamCounters& counters, const IngestBound& bound) {
  if (auto* s = IngestStream::start(engine, counters, bound)) return s;
  return refused_ingest_stream(grpc::Status(
      grpc::StatusCode::RESOURCE_EXHAUSTED,
      join("too many ingest streams (", bound.max_streams,
           ", server.max_ingest_streams), none without a request for ", bound.gives_way_s,
           " s (server.stream_gives_way_s); try again when one has ended")));
}

int close_idle_ingest_streams(StreamCounters& counters, double idle_s) {
  std::vector<std::shared_ptr<IdleClosable>> open;
  {
    std::lock_guard<std::mutex> lock(counters.live_mu);
    std::erase_if(counters.live, [](const auto& w) { return w.expired(); });
    for (const auto& w : counters.live)
      if (auto s = w.lock()) open.push_back(std::move(s));
  }
  // Closed outside the registry's lock: Finish may run reactions of its own.
  const int64_t now = steady_ns(), idle = int64_t(idle_s * 1e9);
  const std::string why = join("no request for ", idle_s,
                               " s (server.stream_idle_s): idle ingest stream closed; reconnect "
                               "to feed");
  int closed = 0;
  for (const auto& s : open) closed += s->close_if_idle(now, idle, why);
  return closed;
}

grpc::ServerWriteReactor<pb::SubscribeFilletsResponse>* new_subscription(
    ResultsHub& hub, const pb::SubscribeFilletsRequest& request, StreamCounters& counters,
    grpc::CallbackServerContext* ctx, int max_subscriptions) {
  std::shared_ptr<Evictable> behind;
  std::shared_ptr<Subscription> s;
  {
    std::lock_guard<std::mutex> lock(counters.subs_mu);
    std::erase_if(counters.subs, [](const auto& w) { return w.expired(); });
    if (int(counters.subs.size()) >= max_subscriptions) {
      // Full: the stream furthest behind gives way, if one is behind at all (a client that
      // stopped reading); streams that keep up are never cut for a newcomer.
      auto most = counters.subs.end();
      uint64_t furthest = kBehindResults;
      for (auto it = counters.subs.begin(); it != counters.subs.end(); ++it)
        if (auto live = it->lock())
          if (const uint64_t b = live->backlog(); b > furthest) furthest = b, most = it;
      if (most == counters.subs.end())
        return refused_subscription(
            grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                         "too many result subscriptions (" + std::to_string(max_subscriptions) +
                             ", server.max_subscriptions), and none has fallen behind"));
      behind = most->lock();
      counters.subs.erase(most);  // so that no other newcomer takes the same place
    }
    s = Subscription::make(hub, counters, ctx);
    counters.subs.push_back(s);  // counted at once: newcomers at the same time see it
  }
  if (behind) {
    behind->give_way();  // outside the registry's lock: it may run reactions
    hub.note_dropped();
  }
  return s->start(request);
}

}  // namespace rangex
