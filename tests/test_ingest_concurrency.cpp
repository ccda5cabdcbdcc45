// Ingest as a plant's clients can stress it: many streams on many lanes, two streams on one
// lane with overlapping encoder ranges, duplicates and backwards lines interleaved, encoder
// jumps up to 2^62 and resets, subscribers coming and going, calibration and threshold
// changes, statistics polled all the while, a feeder whose connection is cut, a worker that
// stalls, a store that is locked, a server stopped in the middle. Built twice, plainly and
// under ThreadSanitizer (whose reports fail the run). Every test is bounded: a hang aborts the
// test with a message instead of stalling CI.
//
// The lines come from a simulated recording made by `rangexctl simulate` (ctest fixture,
// RANGEX_CONCURRENCY_DATA); each server lane replays one of its lanes.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <climits>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "backends/cpu/cpu_backend.h"
#include "core/plant_config.h"
#include "core/recording.h"
#include "feeder.h"
#include "grpc_raw.h"
#include "line_source.h"
#include "pipeline/lane_processor.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/server.h"
#include "temp_dir.h"

using namespace rangex;
namespace pb = rangex::v1;
using namespace std::chrono_literals;

namespace {

// Under ThreadSanitizer (about 50 times slower) the largest case runs at a quarter of the
// plant: 4 lanes, 8 streams, 4 steady and 4 churning subscribers, the same overlaps, resends
// and control changes (at half the plant it took 345 s of the test command's 2 cores). The
// plain build runs all of it.
#if defined(__SANITIZE_THREAD__)
constexpr int kScale = 4;
#else
constexpr int kScale = 1;
#endif

// Aborts the process when a test outlives its bound: a hang is a failure, not a stall.
class Bound {
 public:
  explicit Bound(int seconds) {
    name_ = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    t_ = std::thread([this, seconds] {
      std::unique_lock<std::mutex> lock(mu_);
      if (!cv_.wait_for(lock, std::chrono::seconds(seconds), [&] { return done_; })) {
        std::fprintf(stderr, "\n%s did not finish within %d s: it hung\n", name_.c_str(), seconds);
        std::fflush(stderr);
        std::_Exit(3);
      }
    });
  }
  ~Bound() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      done_ = true;
    }
    cv_.notify_all();
    t_.join();
  }

 private:
  std::string name_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread t_;
};

std::string data_dir() {
  const char* d = std::getenv("RANGEX_CONCURRENCY_DATA");
  return d ? d : "";
}

// Every lane of the plant: the shipped rig, 16 lanes.
PlantConfig plant(int lanes) {
  PlantConfig p = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  const LaneConfig proto = p.lanes.front();
  p.lanes.clear();
  for (int i = 0; i < lanes; ++i) {
    LaneConfig l = proto;
    l.id = i;
    p.lanes.push_back(l);
  }
  return p;
}

ServerOptions options(const test::TempDir& t) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str("data");
  o.engine.queue_lines = 4096;
  o.engine.backend = cpu_request();
  o.engine.images = false;
  // Long enough that a slow batch is not a stall: under TSan on CI's loaded 2 cores one batch
  // took over 2 s (stop 95), and a test that waits for the store's failure saw that instead.
  o.engine.stall_s = 30;
  // A hang bound: under TSan on a loaded machine a 4,096-line queue took over 30 s to drain.
  o.engine.drain_timeout_s = 300;
  return o;
}

std::shared_ptr<grpc::Channel> connect(const RangexServer& s) {
  return rangex_channel(s.address());
}

// Lines of the recording's lanes, read on demand (every thread reads its own copy).
class Lines {
 public:
  Lines() : rec_(data_dir()) {}
  int64_t count() const { return rec_.lines(); }
  int sources() const { return int(rec_.lanes().size()); }
  int64_t first_encoder() {
    pb::LineScan l;
    get(0, 0, 0, l);
    return l.encoder();
  }
  // Line n of recording lane `src` as lane `lane`, its encoder moved by `shift`.
  void get(int src, int64_t n, int lane, pb::LineScan& out, int64_t shift = 0) {
    std::lock_guard<std::mutex> lock(mu_);
    rec_.line(src, n, out);
    out.set_lane(lane);
    out.set_encoder(out.encoder() + shift);
    out.clear_calibration_id();  // calibrations change under the suite's feet
  }

 private:
  std::mutex mu_;
  RecordingSource rec_;
};

struct Decided {
  int64_t first_encoder;
  std::string decision;
  size_t bones;
  bool operator==(const Decided& o) const {
    return first_encoder == o.first_encoder && decision == o.decision && bones == o.bones;
  }
};
std::ostream& operator<<(std::ostream& os, const Decided& d) {
  return os << "{" << d.first_encoder << " " << d.decision << " " << d.bones << " bones}";
}

// The decisions of one orderly pass over a recording lane, without the server.
std::vector<Decided> reference(Lines& lines, int src, const LaneConfig& lane, int64_t shift = 0) {
  std::vector<Decided> out;
  CpuBackend cpu;
  cpu.set_lanes({lane});
  LineResults r;
  const int slot = 0;
  LaneProcessor proc(lane, {false, false}, [&](InspectedFillet&& f) {
    out.push_back({f.result.first_encoder, std::string(decision_name(f.result.decision)),
                   f.result.fragments.size()});
  });
  const size_t frame = size_t(lane.frame_width) * lane.frame_height;
  std::vector<uint8_t> frames(2 * frame);
  std::vector<uint16_t> xray(lane.xray.pixels);
  pb::LineScan l;
  for (int64_t n = 0; n < lines.count(); ++n) {
    lines.get(src, n, lane.id, l, shift);
    std::memcpy(frames.data(), l.cam0().data(), frame);
    std::memcpy(frames.data() + frame, l.cam1().data(), frame);
    std::memcpy(xray.data(), l.xray().data(), l.xray().size());
    const int64_t e = l.encoder();
    run_batch(cpu, frames.data(), 1, &slot, r);
    proc.push(r, 0, 1, xray.data(), &e);
  }
  proc.finish();
  return out;
}

// Recording lane 0 holds one fillet: its orderly decision, and the line of the recording 80
// lines into it on the laser side.
struct OneFillet {
  std::vector<Decided> ref;
  int64_t mid = 0;
};
OneFillet one_fillet(Lines& lines, const LaneConfig& lane) {
  OneFillet f;
  f.ref = reference(lines, 0, lane);
  EXPECT_EQ(f.ref.size(), 1u);
  if (!f.ref.empty())
    f.mid = f.ref[0].first_encoder - lines.first_encoder() - lane.xray.delay_lines + 80;
  return f;
}

std::vector<Decided> stored(Store& store, int lane) {
  std::vector<Decided> out;
  for (const StoredFillet& f : store.list_fillets(0, 0, lane, 0, 100000)) {
    size_t bones = 0;
    for (const auto& g : f.fragments) bones += g.kind == "bone";
    out.push_back({f.first_encoder, f.decision, bones});
  }
  return out;
}

struct Ack {
  int lane = 0;
  int64_t encoder = 0;
  bool accepted = false;
  std::string code;
};

// One client stream: lines go out as the window and the server's credit allow; every ack is
// kept with the line it answers.
class Stream {
 public:
  explicit Stream(const std::shared_ptr<grpc::Channel>& ch, int window = 16)
      : stub_(pb::IngestService::NewStub(ch)), window_(window) {
    stream_ = stub_->StreamLines(&ctx_);
    reader_ = std::thread([this] {
      pb::StreamLinesResponse r;
      while (stream_->Read(&r)) {
        std::lock_guard<std::mutex> lock(mu_);
        if (queries_.count(r.sequence())) {
          query_pending_ = false;
        } else {
          Ack& a = acks_[r.sequence()];
          a.accepted = r.accepted();
          a.code = r.error().code();
          ++lines_acked_;
        }
        ++acked_;
        credit_ = r.credit();
        cv_.notify_all();
      }
      std::lock_guard<std::mutex> lock(mu_);
      closed_ = true;
      cv_.notify_all();
    });
  }
  ~Stream() { finish(); }
  // False once the server ended the stream.
  bool send(const pb::LineScan* line) {
    pb::StreamLinesRequest req;
    {
      // Like a plant's feeder: never more in flight than the window and the last credit
      // (this stream's share of the queue); with no credit and nothing in flight, ask for
      // the credit again after a while, never with a line, which a full queue would drop.
      std::unique_lock<std::mutex> lock(mu_);
      while (true) {
        cv_.wait(lock, [&] {
          return closed_ || (!query_pending_ &&
                             (sent_ - acked_ < std::min(window_, credit_) || sent_ == acked_));
        });
        if (closed_) return false;
        if (sent_ - acked_ < std::min(window_, credit_)) break;
        pb::StreamLinesRequest query;
        query.set_sequence(sent_++);
        query.set_credit_query(true);
        queries_.insert(query.sequence());
        query_pending_ = true;
        lock.unlock();
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        const bool open = stream_->Write(query);
        lock.lock();
        if (!open) return false;
      }
      req.set_sequence(sent_++);
      Ack& a = acks_[req.sequence()];
      if (line) {
        a.lane = line->lane();
        a.encoder = line->encoder();
      }
    }
    if (line) *req.mutable_line() = *line;
    return stream_->Write(req);
  }
  void finish() {
    if (finished_) return;
    finished_ = true;
    stream_->WritesDone();
    reader_.join();
    status_ = stream_->Finish();
  }
  // Lines acknowledged (credit queries not counted).
  int64_t acked() {
    std::lock_guard<std::mutex> lock(mu_);
    return lines_acked_;
  }
  // The last line n of a contiguous prefix that was acknowledged.
  std::map<uint64_t, Ack> acks() {
    std::lock_guard<std::mutex> lock(mu_);
    return acks_;
  }
  const grpc::Status& status() const { return status_; }

 private:
  std::unique_ptr<pb::IngestService::Stub> stub_;
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReaderWriter<pb::StreamLinesRequest, pb::StreamLinesResponse>>
      stream_;
  std::thread reader_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<uint64_t, Ack> acks_;
  std::set<uint64_t> queries_;  // sequences that asked for credit, not lines
  bool query_pending_ = false;
  int64_t sent_ = 0, acked_ = 0, lines_acked_ = 0;
  int window_;
  int credit_ = 1 << 20;
  bool closed_ = false, finished_ = false;
  grpc::Status status_;
};

// A subscriber that keeps every result it is sent.
class Subscriber {
 public:
  explicit Subscriber(const std::shared_ptr<grpc::Channel>& ch) {
    auto stub = pb::ResultsService::NewStub(ch);
    reader_ = stub->SubscribeFillets(&ctx_, {});
    t_ = std::thread([this] {
      pb::SubscribeFilletsResponse r;
      while (reader_->Read(&r)) {
        std::lock_guard<std::mutex> lock(mu_);
        uids_.insert(r.fillet().uid());
        lagged_ += r.lagged();
        // Each lane's decisions arrive in the order of its fillets.
        int64_t& last = last_encoder_.try_emplace(r.fillet().lane(), INT64_MIN).first->second;
        out_of_order_ += r.fillet().first_encoder() <= last;
        last = r.fillet().first_encoder();
      }
      status_ = reader_->Finish();
    });
  }
  ~Subscriber() { stop(); }
  void stop() {
    if (stopped_) return;
    stopped_ = true;
    ctx_.TryCancel();
    t_.join();
  }
  // Waits (bounded) for the stream to end by itself, as at a server's shutdown.
  void join() {
    stopped_ = true;
    t_.join();
  }
  std::set<int64_t> uids() {
    std::lock_guard<std::mutex> lock(mu_);
    return uids_;
  }
  uint64_t lagged() {
    std::lock_guard<std::mutex> lock(mu_);
    return lagged_;
  }
  int out_of_order() {
    std::lock_guard<std::mutex> lock(mu_);
    return out_of_order_;
  }
  const grpc::Status& status() const { return status_; }

 private:
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReader<pb::SubscribeFilletsResponse>> reader_;
  std::thread t_;
  std::mutex mu_;
  std::set<int64_t> uids_;
  uint64_t lagged_ = 0;
  std::map<int, int64_t> last_encoder_;
  int out_of_order_ = 0;
  bool stopped_ = false;
  grpc::Status status_;
};

uint64_t total(const std::map<std::string, uint64_t>& m) {
  uint64_t n = 0;
  for (const auto& [k, v] : m) n += v;
  return n;
}

// The accounting every run must satisfy once the server has stopped.
void expect_accounting(RangexServer& server) {
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.received, s.accepted + total(s.refused)) << "received = accepted + refused";
  EXPECT_EQ(s.accepted, s.processed + total(s.dropped)) << "accepted = processed + dropped";
  EXPECT_EQ(s.queue_depth, 0);
}

}  // namespace

TEST(IngestConcurrency, ManyStreamsOverlappingOnLanesHostileLinesSubscribersAndControl) {
  ASSERT_FALSE(data_dir().empty()) << "RANGEX_CONCURRENCY_DATA is not set";
  Bound bound(600);
  constexpr int kLanes = 16 / kScale, kSubscribers = 16 / kScale;
  test::TempDir t;
  const PlantConfig p = plant(kLanes);
  Lines lines;
  const int64_t N = lines.count();
  std::vector<std::vector<Decided>> ref;
  for (int s = 0; s < lines.sources(); ++s) ref.push_back(reference(lines, s, p.lanes[0]));

  RangexServer server(p, options(t));
  auto ch = connect(server);
  std::atomic<bool> feeding{true};

  // Subscribers for the whole run, and as many that come and go.
  std::vector<std::unique_ptr<Subscriber>> steady;
  for (int i = 0; i < kSubscribers; ++i) steady.push_back(std::make_unique<Subscriber>(ch));
  std::vector<std::thread> churn;
  for (int i = 0; i < kSubscribers; ++i)
    churn.emplace_back([&, i] {
      while (feeding) {
        Subscriber s(ch);
        std::this_thread::sleep_for(std::chrono::milliseconds(30 + 17 * i));
        s.stop();
      }
    });
  // Statistics and lanes polled all the while; they must always answer.
  std::atomic<int> polls{0};
  std::thread poller([&] {
    auto ctl = pb::ControlService::NewStub(ch);
    uint64_t last_received = 0;
    while (feeding) {
      grpc::ClientContext c1, c2;
      c1.set_deadline(std::chrono::system_clock::now() + 10s);
      c2.set_deadline(std::chrono::system_clock::now() + 10s);
      pb::GetStatisticsResponse st;
      pb::ListLanesResponse ll;
      ASSERT_TRUE(ctl->GetStatistics(&c1, {}, &st).ok());
      ASSERT_TRUE(ctl->ListLanes(&c2, {}, &ll).ok());
      EXPECT_GE(st.lines_received(), last_received);
      last_received = st.lines_received();
      ++polls;
      std::this_thread::sleep_for(5ms);
    }
  });
  // Calibrations activated and thresholds set (to what they are) on every lane while lines
  // flow: each change waits for a quiet boundary; decisions must not change.
  std::thread control([&] {
    auto cal = pb::CalibrationService::NewStub(ch);
    auto ctl = pb::ControlService::NewStub(ch);
    for (int k = 0; feeding; ++k) {
      const int lane = k % kLanes;
      grpc::ClientContext c1, c2, c3;
      pb::UploadCalibrationRequest up;
      up.set_lane(lane);
      up.set_id("same-rig-" + std::to_string(k));
      up.set_yaml("laser_plane: {normal: [0, 1, 0], offset_mm: 0.0}\n");
      up.set_who("suite");
      pb::UploadCalibrationResponse ur;
      ASSERT_TRUE(cal->UploadCalibration(&c1, up, &ur).ok());
      pb::ActivateCalibrationRequest act;
      act.set_lane(lane);
      act.set_id(up.id());
      act.set_who("suite");
      act.set_force(true);
      pb::ActivateCalibrationResponse ar;
      ASSERT_TRUE(cal->ActivateCalibration(&c2, act, &ar).ok());
      pb::UpdateLaneThresholdsRequest th;
      th.set_lane(lane);
      th.set_z_threshold(p.lanes[0].inspection.z_threshold);
      th.set_who("suite");
      pb::UpdateLaneThresholdsResponse tr;
      ASSERT_TRUE(ctl->UpdateLaneThresholds(&c3, th, &tr).ok());
      std::this_thread::sleep_for(40ms);
    }
  });

  // Per lane: stream A sends every line; once a third is acknowledged, stream B (a camera
  // that reconnected while its old stream is still open) resends from a little before that
  // point and races A over the rest.
  std::vector<std::thread> lanes;
  std::vector<std::unique_ptr<Stream>> a_streams(kLanes), b_streams(kLanes);
  for (int lane = 0; lane < kLanes; ++lane) {
    a_streams[lane] = std::make_unique<Stream>(ch);
    b_streams[lane] = std::make_unique<Stream>(ch);
    lanes.emplace_back([&, lane] {
      const int src = lane % lines.sources();
      Stream& a = *a_streams[lane];
      Stream& b = *b_streams[lane];
      std::thread second([&] {
        while (a.acked() < N / 3) std::this_thread::sleep_for(1ms);
        pb::LineScan l;
        for (int64_t n = a.acked() - 8; n < N; ++n) {
          lines.get(src, n, lane, l);
          if (!b.send(&l)) break;
        }
        b.finish();
      });
      pb::LineScan l;
      for (int64_t n = 0; n < N; ++n) {
        lines.get(src, n, lane, l);
        if (!a.send(&l)) break;
      }
      a.finish();
      second.join();
    });
  }
  // A hostile client on lanes 0..3: repeats, counts from before a lane's first line, unknown
  // lanes, wrong sizes, empty requests, encoders beyond 2^62.
  std::map<std::string, uint64_t> hostile_sent;
  std::thread hostile([&] {
    Stream h(ch, 4);
    pb::LineScan l;
    const int64_t first = lines.first_encoder();
    for (int k = 0; k < 200; ++k) {
      const int lane = k % 4;
      switch (k % 6) {
        case 0:  // a line already accepted (or about to be: then its duplicate is refused)
          lines.get(lane % lines.sources(), 0, lane, l);
          ++hostile_sent["DUPLICATE_LINE"];
          break;
        case 1:  // never accepted, behind the lane's latest
          lines.get(lane % lines.sources(), 0, lane, l, -20 - k);
          ++hostile_sent["ENCODER_BACKWARDS"];
          break;
        case 2:
          lines.get(0, 0, 99, l);
          ++hostile_sent["UNKNOWN_LANE"];
          break;
        case 3:
          lines.get(0, 0, lane, l);
          l.mutable_cam0()->resize(1000);
          ++hostile_sent["WRONG_FRAME_SIZE"];
          break;
        case 4:
          ++hostile_sent["MISSING_LINE"];
          ASSERT_TRUE(h.send(nullptr));
          continue;
        case 5:
          lines.get(0, 0, lane, l);
          l.set_encoder(first + (int64_t(1) << 62));
          ++hostile_sent["ENCODER_OUT_OF_RANGE"];
          break;
      }
      // The duplicates and backwards lines go only once the lane has moved on.
      if (k % 6 < 2)
        while (a_streams[lane]->acked() < 50) std::this_thread::sleep_for(1ms);
      ASSERT_TRUE(h.send(&l));
    }
    h.finish();
    for (const auto& [seq, ack] : h.acks()) {
      EXPECT_FALSE(ack.accepted) << "hostile line " << seq << " was accepted";
    }
  });

  for (auto& th : lanes) th.join();
  hostile.join();
  feeding = false;
  for (auto& th : churn) th.join();
  poller.join();
  control.join();
  EXPECT_GT(polls, 10);
  ASSERT_TRUE(server.shutdown());
  for (auto& s : steady) s->join();

  // Each count accepted exactly once per lane, from one stream or the other.
  for (int lane = 0; lane < kLanes; ++lane) {
    std::map<int64_t, int> accepted;
    for (Stream* s : {a_streams[lane].get(), b_streams[lane].get()}) {
      EXPECT_TRUE(s->status().ok()) << s->status().error_message();
      for (const auto& [seq, ack] : s->acks()) {
        if (ack.accepted)
          ++accepted[ack.encoder];
        else
          EXPECT_EQ(ack.code, "DUPLICATE_LINE") << "lane " << lane << " encoder " << ack.encoder;
      }
    }
    ASSERT_EQ(int64_t(accepted.size()), N) << "lane " << lane;
    for (const auto& [e, k] : accepted) EXPECT_EQ(k, 1) << "lane " << lane << " encoder " << e;
  }
  expect_accounting(server);
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.accepted, uint64_t(kLanes * N));
  for (const char* code : {"ENCODER_BACKWARDS", "UNKNOWN_LANE", "WRONG_FRAME_SIZE", "MISSING_LINE",
                           "ENCODER_OUT_OF_RANGE"})
    EXPECT_EQ(s.refused.at(code), hostile_sent[code]) << code;
  EXPECT_GE(s.refused.at("DUPLICATE_LINE"), hostile_sent["DUPLICATE_LINE"]);
  EXPECT_TRUE(s.dropped.empty());

  // Decisions equal those of one orderly pass; every steady subscriber saw every one.
  std::set<int64_t> uids;
  for (int lane = 0; lane < kLanes; ++lane) {
    EXPECT_EQ(stored(server.store(), lane), ref[lane % lines.sources()]) << "lane " << lane;
    for (const auto& f : server.store().list_fillets(0, 0, lane, 0, 100000)) uids.insert(f.uid);
  }
  for (auto& sub : steady) {
    EXPECT_EQ(sub->lagged(), 0u);
    EXPECT_EQ(sub->uids(), uids);
    EXPECT_EQ(sub->out_of_order(), 0);
  }
}

TEST(IngestConcurrency, EncoderJumpsAndResetsTakeBoundedTimeAndFailSafe) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(300);
  test::TempDir t;
  const PlantConfig p = plant(2);
  Lines lines;
  const int64_t N = lines.count(), first = lines.first_encoder();
  const auto [ref, mid] = one_fillet(lines, p.lanes[0]);
  ASSERT_EQ(ref.size(), 1u);
  ASSERT_NE(ref[0].decision, "not_inspected");

  RangexServer server(p, options(t));
  auto ch = connect(server);
  auto send_pass = [&](int64_t cut, int64_t jump, int64_t shift) {
    // One pass over the recording on lane 0, encoders moved by `shift`, and from line
    // `cut` on by `jump` more.
    Stream s(ch);
    pb::LineScan l;
    for (int64_t n = 0; n < N; ++n) {
      lines.get(0, n, 0, l, shift + (n >= cut ? jump : 0));
      EXPECT_TRUE(s.send(&l));
    }
    s.finish();
    for (const auto& [seq, ack] : s.acks()) EXPECT_TRUE(ack.accepted) << ack.code;
    return l.encoder();
  };
  auto until_decided = [&](size_t fillets) {
    while (server.store().count_fillets() < int64_t(fillets)) std::this_thread::sleep_for(2ms);
  };
  const int64_t J = (int64_t(1) << 62) - 4 * N - first;
  // 1. A jump of about 2^62 in the middle of the fillet: it ends not inspected, at once.
  send_pass(mid, J, 0);
  // 2. Back to the start: far behind the lane's latest, an encoder reset; the whole fillet
  //    comes again and is inspected as in an orderly pass.
  send_pass(N, 0, 0);
  // 3. A reset commanded through the control plane, then a pass at other counts.
  {
    auto ctl = pb::ControlService::NewStub(ch);
    grpc::ClientContext c;
    pb::ResetLaneRequest req;
    req.set_lane(0);
    req.set_who("line-engineer");
    req.set_reason("PLC replaced");
    pb::ResetLaneResponse resp;
    ASSERT_TRUE(ctl->ResetLane(&c, req, &resp).ok());
    EXPECT_TRUE(resp.lane().fed());
  }
  send_pass(N, 0, 5000);
  // 4. Jumps of 1e8 and 1.5e11 in fillets' middles: within nothing like 1.5 s or 7 minutes.
  send_pass(mid, 100'000'000, 20'000);
  const int64_t last = send_pass(mid, 150'000'000'000, 200'000'000);
  // 5. A gap of 20 lines inside the fillet (within the horizon): bridged, the fillet is
  //    marked as missing lines.
  {
    Stream s(ch);
    pb::LineScan l;
    const int64_t shift = last + 10 - first;
    for (int64_t n = 0; n < N; ++n) {
      if (n >= mid && n < mid + 20) continue;
      lines.get(0, n, 0, l, shift);
      EXPECT_TRUE(s.send(&l));
    }
    s.finish();
  }
  until_decided(9);
  {
    auto ctl = pb::ControlService::NewStub(ch);
    grpc::ClientContext c;
    pb::ListLanesResponse ll;
    ASSERT_TRUE(ctl->ListLanes(&c, {}, &ll).ok());
    EXPECT_EQ(ll.lanes(0).last_encoder(), last + 10 + N - 1);
    EXPECT_GE(ll.lanes(0).restarts(), 5u);  // jump, reset, commanded reset, two jumps
    EXPECT_FALSE(ll.lanes(1).fed());
  }
  ASSERT_TRUE(server.shutdown());
  const auto all = server.store().list_fillets(0, 0, 0, 0, 1000);
  std::vector<std::string> got;
  for (const auto& f : all) got.push_back(f.decision + ": " + f.reason);
  // Each cut fillet is two not inspected records (before and after the cut); the whole ones
  // are decided as in an orderly pass.
  ASSERT_EQ(all.size(), 9u) << ::testing::PrintToString(got);
  auto has = [](const StoredFillet& f, const char* what) {
    return f.reason.find(what) != std::string::npos;
  };
  EXPECT_EQ(all[0].decision, "not_inspected");
  EXPECT_TRUE(has(all[0], "encoder jumped")) << all[0].reason;
  EXPECT_EQ(all[1].decision, "not_inspected");  // the rest of it, after the jump
  EXPECT_EQ(all[2].decision, ref[0].decision) << all[2].reason;
  EXPECT_EQ(all[3].decision, ref[0].decision) << all[3].reason;
  for (int k : {4, 5, 6, 7}) EXPECT_EQ(all[k].decision, "not_inspected") << k;
  EXPECT_TRUE(has(all[4], "encoder jumped")) << all[4].reason;
  EXPECT_TRUE(has(all[6], "encoder jumped")) << all[6].reason;
  EXPECT_EQ(all[8].decision, "not_inspected");
  EXPECT_TRUE(has(all[8], "lines missing")) << all[8].reason;
  bool audited = false;
  for (const auto& e : server.store().audit_log(50))
    audited |= e.find(" anonymous@ipv4:127.0.0.1:") != std::string::npos &&
               e.find(" lane.reset lane 0 PLC replaced") != std::string::npos &&
               e.find("line-engineer") == std::string::npos;  // claimed, not proved
  EXPECT_TRUE(audited);
  expect_accounting(server);
}

TEST(IngestConcurrency, ServerStoppedInTheMiddleEndsEveryStreamAndDecidesWhatItTook) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(300);
  constexpr int kLanes = 8;
  test::TempDir t;
  const PlantConfig p = plant(kLanes);
  Lines lines;
  const int64_t N = lines.count();
  RangexServer server(p, options(t));
  auto ch = connect(server);
  std::vector<std::unique_ptr<Subscriber>> subs;
  for (int i = 0; i < 4; ++i) subs.push_back(std::make_unique<Subscriber>(ch));
  std::vector<std::unique_ptr<Stream>> streams;
  for (int lane = 0; lane < kLanes; ++lane) streams.push_back(std::make_unique<Stream>(ch));
  std::vector<std::thread> feeders;
  std::atomic<int> past_third{0};
  for (int lane = 0; lane < kLanes; ++lane) {
    feeders.emplace_back([&, lane] {
      Stream& s = *streams[lane];
      pb::LineScan l;
      bool counted = false;
      for (int64_t n = 0; n < N; ++n) {
        lines.get(lane % lines.sources(), n, lane, l);
        if (!s.send(&l)) break;
        if (!counted && n > N / 3) {
          counted = true;
          ++past_third;
        }
      }
      s.finish();
    });
  }
  while (past_third < kLanes) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(server.shutdown());  // while every lane is streaming
  for (auto& f : feeders) f.join();
  for (auto& s : subs) s->join();  // subscriptions end with the server
  uint64_t acked_accepted = 0;
  for (auto& s : streams)
    for (const auto& [seq, ack] : s->acks()) {
      acked_accepted += ack.accepted;
      if (!ack.accepted && !ack.code.empty()) EXPECT_EQ(ack.code, "SHUTTING_DOWN");
    }
  expect_accounting(server);
  const EngineStats st = server.engine().stats();
  EXPECT_EQ(st.accepted, acked_accepted);
  EXPECT_GT(st.refused.count("SHUTTING_DOWN") + st.accepted, 0u);
  // Fillets cut by the stop are not inspected, never passed on half their lines.
  for (const StoredFillet& f : server.store().list_fillets(0, 0, -1, 0, 1000))
    if (f.decision == "pass") EXPECT_EQ(f.reason, "") << f.lane;
  for (const StoredFillet& f : server.store().list_fillets(0, 0, -1, 0, 1000))
    if (f.reason.find("coming in") != std::string::npos) EXPECT_EQ(f.decision, "not_inspected");
}

TEST(IngestConcurrency, FeederReconnectsResendsAndNoLineIsDecidedTwice) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(300);
  test::TempDir t;
  const PlantConfig p = plant(2);
  Lines lines;
  std::vector<std::vector<Decided>> ref;
  for (int s = 0; s < 2; ++s) ref.push_back(reference(lines, s, p.lanes[0]));
  ServerOptions o = options(t);
  o.max_connection_age_ms = 300;  // the server cuts every connection after 0.3 + 0.3 s
  RangexServer server(p, o);
  RecordingSource src(data_dir());
  FeedOptions fo;
  fo.window = 32;
  fo.rate = 400;  // lines/s per lane: the feed outlives several connections
  fo.reconnect_for_s = 30;
  std::string told;  // what the feeder said, shown if it fails
  fo.log = [&told](const std::string& m) { told += m + "\n"; };
  const FeedReport r = Feeder(connect(server), fo).run(src);
  EXPECT_TRUE(r.status.ok()) << r.status.error_message() << "\n" << told;
  EXPECT_GE(r.reconnects, 1u);
  // Every connection took lines, or answered the wait to be settled, before the server cut
  // it: each reconnect waits the first backoff step (0.1 s), not one doubled per cut (0.1,
  // 0.2, ... 1.6, 2 s), however many cuts fall while the last fillets are being decided.
  EXPECT_LT(r.longest_backoff_ms, 1600u) << r.reconnects << " reconnects\n" << told;
  EXPECT_EQ(r.sent, uint64_t(2 * lines.count()));
  EXPECT_EQ(r.accepted, r.sent);
  EXPECT_EQ(r.refused_total(), 0u);
  ASSERT_TRUE(server.shutdown());
  const EngineStats s = server.engine().stats();
  EXPECT_EQ(s.accepted, r.sent);
  EXPECT_LE(s.refused.count("DUPLICATE_LINE") ? s.refused.at("DUPLICATE_LINE") : 0, r.resent);
  for (int lane = 0; lane < 2; ++lane) EXPECT_EQ(stored(server.store(), lane), ref[lane]);
  expect_accounting(server);
}

TEST(IngestConcurrency, StalledWorkerTurnsHealthNotServingAndBack) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(120);
  test::TempDir t;
  const PlantConfig p = plant(2);
  Lines lines;
  std::mutex mu;
  std::condition_variable cv;
  bool stall = false, stalled = false;
  ServerOptions o = options(t);
  o.engine.stall_s = 0.3;
  o.engine.exit_after_s = 0.6;
  std::atomic<int> fatal{0};
  o.on_fatal = [&](const Health&) { ++fatal; };
  o.engine.batch_hook = [&] {  // a worker stuck in a batch, as on a hung disk
    std::unique_lock<std::mutex> lock(mu);
    stalled = stall;
    cv.notify_all();
    cv.wait(lock, [&] { return !stall; });
  };
  RangexServer server(p, o);
  auto ch = connect(server);
  EXPECT_EQ(test::health(ch, ""), 1);
  {
    std::lock_guard<std::mutex> lock(mu);
    stall = true;
  }
  Stream s(ch);
  pb::LineScan l;
  for (int n = 0; n < 40; ++n) {
    lines.get(0, n, 0, l);
    ASSERT_TRUE(s.send(&l));
  }
  {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return stalled; });
  }
  while (test::health(ch, "") != 2) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(test::health(ch, "rangex.v1.IngestService"), 2);
  EXPECT_EQ(test::health(ch, "rangex.v1.ControlService"), 1);  // where to ask why
  EXPECT_EQ(test::health(ch, "rangex.v1.ResultsService"), 1);
  {
    auto ctl = pb::ControlService::NewStub(ch);
    grpc::ClientContext c;
    pb::GetStatisticsResponse st;
    ASSERT_TRUE(ctl->GetStatistics(&c, {}, &st).ok());  // answers while the worker is stuck
    EXPECT_FALSE(st.serving());
    ASSERT_GE(st.health_size(), 1);
    EXPECT_NE(st.health(0).find("worker stalled"), std::string::npos) << st.health(0);
  }
  while (fatal == 0) std::this_thread::sleep_for(10ms);  // rangexd would exit here
  {
    std::lock_guard<std::mutex> lock(mu);
    stall = false;
  }
  cv.notify_all();
  while (test::health(ch, "") != 1) std::this_thread::sleep_for(10ms);
  s.finish();
  ASSERT_TRUE(server.shutdown());
  EXPECT_EQ(fatal, 1);
  expect_accounting(server);
}

TEST(IngestConcurrency, LockedStoreTurnsHealthNotServingAndNoDecisionIsLost) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(300);
  test::TempDir t;
  const PlantConfig p = plant(1);
  Lines lines;
  const std::vector<Decided> ref = reference(lines, 0, p.lanes[0]);
  RangexServer server(p, options(t));
  auto ch = connect(server);
  // Another process (a backup, an audit query) holds the database.
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(t.str("data/rangex.sqlite").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr), SQLITE_OK);
  Subscriber sub(ch);
  {
    Stream s(ch);
    pb::LineScan l;
    for (int64_t n = 0; n < lines.count(); ++n) {
      lines.get(0, n, 0, l);
      ASSERT_TRUE(s.send(&l));
    }
    s.finish();
  }
  // Wait for the store's failure itself: a slow batch can make health NOT_SERVING for a moment
  // on its own, and that says nothing about the store.
  while (test::health(ch, "rangex.v1.ResultsService") != 2) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(test::health(ch, ""), 2);
  EXPECT_TRUE(sub.uids().empty());  // nothing published that is not stored
  sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  while (test::health(ch, "") != 1) std::this_thread::sleep_for(10ms);
  while (sub.uids().size() < ref.size()) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(server.shutdown());
  EXPECT_EQ(stored(server.store(), 0), ref);
  EXPECT_GE(server.engine().stats().store_errors, 1u);
  expect_accounting(server);
}

TEST(IngestConcurrency, ALaneThatStopsBeingFedEndsItsOpenFilletNotInspected) {
  ASSERT_FALSE(data_dir().empty());
  Bound bound(180);
  test::TempDir t;
  const PlantConfig p = plant(2);
  Lines lines;
  const int64_t N = lines.count();
  const auto [ref, mid] = one_fillet(lines, p.lanes[0]);
  ASSERT_EQ(ref.size(), 1u);
  ServerOptions o = options(t);
  // Not shorter: a gap this long while the feeder still sends (a descheduled client under TSan on
  // a loaded machine) would end the fillet early, and the test would count one fillet too many.
  o.engine.idle_close_s = 2;
  RangexServer server(p, o);
  auto ch = connect(server);
  auto send = [&](int64_t from, int64_t to) {
    Stream s(ch);
    pb::LineScan l;
    for (int64_t n = from; n < to; ++n) {
      lines.get(0, n, 0, l);
      ASSERT_TRUE(s.send(&l));
    }
    s.finish();
  };
  send(0, mid);  // the feeder dies in the middle of a fillet
  while (server.store().count_fillets() < 1) std::this_thread::sleep_for(10ms);
  const auto cut = server.store().list_fillets(0, 0, 0, 0, 10);
  EXPECT_EQ(cut[0].decision, "not_inspected");
  EXPECT_NE(cut[0].reason.find("stopped being fed"), std::string::npos) << cut[0].reason;
  {
    auto ctl = pb::ControlService::NewStub(ch);
    grpc::ClientContext c1, c2;
    pb::GetStatisticsResponse st;
    ASSERT_TRUE(ctl->GetStatistics(&c1, {}, &st).ok());
    EXPECT_TRUE(st.serving());  // the server can still inspect; it says what needs a look
    ASSERT_GE(st.warnings_size(), 1);
    EXPECT_NE(st.warnings(0).find("lane 0 stopped being fed"), std::string::npos) << st.warnings(0);
    pb::ListLanesResponse ll;
    ASSERT_TRUE(ctl->ListLanes(&c2, {}, &ll).ok());
    EXPECT_NE(ll.lanes(0).last_restart().find("stopped being fed"), std::string::npos);
    EXPECT_FALSE(ll.lanes(0).fillet_in_progress());
  }
  send(mid, N);  // it comes back where it stopped: the rest of that fillet is not passed
  ASSERT_TRUE(server.shutdown());
  const auto all = server.store().list_fillets(0, 0, 0, 0, 10);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[1].decision, "not_inspected") << all[1].reason;
  expect_accounting(server);
}
