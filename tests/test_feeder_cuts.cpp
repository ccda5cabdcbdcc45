// The feeder against a server that ends its streams where a real one may (a server recycling
// its connections, one shutting down). A small IngestService of its own, so that where each
// cut falls is set by the test, not left to timing as on rangexd under load.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "feeder.h"
#include "line_source.h"
#include "rangex/v1/rangex.grpc.pb.h"

namespace rangex {
namespace {

namespace pb = v1;

constexpr int64_t kLines = 40;  // per lane, lanes 0 and 1, counts 0..39

class FewLines : public LineSource {
 public:
  std::vector<int> lanes() const override { return {0, 1}; }
  int64_t lines() const override { return kLines; }
  void line(int lane_index, int64_t n, pb::LineScan& out) override {
    out.Clear();
    out.set_lane(lane_index);
    out.set_encoder(n);
  }
};

// How the server ends its streams.
struct Cuts {
  int handed_back_streams = 0;      // the first streams hand their first line back and end
  int unsettled_answers = 0;        // once every line is in, this many queries answer unsettled,
  bool cut_each_unsettled = false;  // each such answer followed by the stream's end
  bool cut_after_settled = false;   // the stream that answers settled ends with an error
};

// Takes every line at once (its outcome durable at once); says a lane is settled past its
// last line only after `unsettled_answers` queries have found every line in.
class CuttingIngest final : public pb::IngestService::Service {
 public:
  explicit CuttingIngest(Cuts c) : cuts_(c) {}

  grpc::Status StreamLines(
      grpc::ServerContext*,
      grpc::ServerReaderWriter<pb::StreamLinesResponse, pb::StreamLinesRequest>* s) override {
    pb::StreamLinesRequest q;
    while (s->Read(&q)) {
      pb::StreamLinesResponse r;
      r.set_sequence(q.sequence());
      r.set_credit(1000);
      r.set_server_epoch(7);
      std::unique_lock<std::mutex> lock(mu_);
      if (q.credit_query()) {
        const bool all_in =
            int64_t(last_.size()) == 2 && last_[0] == kLines - 1 && last_[1] == kLines - 1;
        const bool settled = all_in && unsettled_answered_ >= cuts_.unsettled_answers;
        if (all_in && !settled) ++unsettled_answered_;
        for (const auto& [lane, last] : last_) {
          pb::LaneProgress* p = r.add_lanes();
          p->set_lane(lane);
          p->set_durable_encoder(last);
          if (settled) p->set_settled_encoder(last);
        }
        lock.unlock();
        s->Write(r);
        if (all_in && !settled && cuts_.cut_each_unsettled)
          return grpc::Status(grpc::StatusCode::UNAVAILABLE, "cut while settling");
        if (settled && cuts_.cut_after_settled)
          return grpc::Status(grpc::StatusCode::UNAVAILABLE, "cut after settled");
        continue;
      }
      if (handed_back_ < cuts_.handed_back_streams) {
        ++handed_back_;
        lock.unlock();
        r.mutable_error()->set_code("SHUTTING_DOWN");
        r.mutable_error()->set_message("stopping");
        s->Write(r);
        return grpc::Status(grpc::StatusCode::UNAVAILABLE, "stopping");
      }
      const pb::LineScan& l = q.line();
      auto it = last_.find(l.lane());
      if (it != last_.end() && l.encoder() <= it->second) {
        r.mutable_error()->set_code("DUPLICATE_LINE");
      } else {
        last_[l.lane()] = l.encoder();
        r.set_accepted(true);
        ++taken_;
      }
      r.set_durable_encoder(last_[l.lane()]);
      lock.unlock();
      s->Write(r);
    }
    return grpc::Status::OK;
  }

  int64_t taken() {
    std::lock_guard<std::mutex> lock(mu_);
    return taken_;
  }

 private:
  const Cuts cuts_;
  std::mutex mu_;
  std::map<int, int64_t> last_;
  int unsettled_answered_ = 0;
  int handed_back_ = 0;
  int64_t taken_ = 0;
};

struct Fed {
  FeedReport report;
  int64_t taken = 0;
  std::string told;
};

Fed feed_against(Cuts c) {
  CuttingIngest service(c);
  grpc::ServerBuilder b;
  int port = 0;
  b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  b.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = b.BuildAndStart();
  EXPECT_GT(port, 0);
  Fed f;
  FeedOptions o;
  o.window = 8;
  o.reconnect_for_s = 20;  // a feeder that stops making progress gives up: no hang
  o.settle_for_s = 20;
  o.log = [&f](const std::string& m) { f.told += m + "\n"; };
  FewLines lines;
  auto channel =
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  f.report = Feeder(channel, o).run(lines);
  f.taken = service.taken();
  server->Shutdown();
  return f;
}

TEST(FeederCuts, AStreamCutAfterEveryOutcomeIsSettledIsNotTheFeedsFailure) {
  Cuts c;
  c.cut_after_settled = true;
  const Fed f = feed_against(c);
  EXPECT_TRUE(f.report.status.ok()) << f.report.status.error_message() << "\n" << f.told;
  EXPECT_TRUE(f.report.settled);
  EXPECT_EQ(f.report.reconnects, 0u);
  EXPECT_EQ(f.report.sent, uint64_t(2 * kLines));
  EXPECT_EQ(f.report.accepted, f.report.sent);
  EXPECT_EQ(f.taken, 2 * kLines);
  EXPECT_NE(f.told.find("cut after settled) after every outcome was stored"), std::string::npos)
      << f.told;
}

TEST(FeederCuts, StreamsCutWhileTheLastFilletsSettleWaitTheFirstBackoffStep) {
  Cuts c;
  c.unsettled_answers = 6;
  c.cut_each_unsettled = true;
  const Fed f = feed_against(c);
  EXPECT_TRUE(f.report.status.ok()) << f.report.status.error_message() << "\n" << f.told;
  EXPECT_TRUE(f.report.settled);
  EXPECT_EQ(f.report.reconnects, 6u) << f.told;
  // Each of those streams answered: none waits longer than the first step (doubled per cut
  // it would reach 0.1, 0.2, 0.4, 0.8, 1.6, 2 s).
  EXPECT_EQ(f.report.longest_backoff_ms, 100u) << f.told;
  EXPECT_EQ(f.report.accepted, f.report.sent);
  EXPECT_EQ(f.taken, 2 * kLines);
}

TEST(FeederCuts, AServerHandingLinesBackIsAskedLessOftenEachTime) {
  Cuts c;
  c.handed_back_streams = 4;
  const Fed f = feed_against(c);
  EXPECT_TRUE(f.report.status.ok()) << f.report.status.error_message() << "\n" << f.told;
  EXPECT_TRUE(f.report.settled);
  EXPECT_EQ(f.report.handed_back, 4u);
  EXPECT_EQ(f.report.reconnects, 4u) << f.told;
  // It answered each stream's query, but took nothing: 0.1, 0.2, 0.4, 0.8 s.
  EXPECT_EQ(f.report.longest_backoff_ms, 800u) << f.told;
  EXPECT_EQ(f.report.refused_total(), 0u);
  EXPECT_EQ(f.report.accepted, f.report.sent);
  EXPECT_EQ(f.taken, 2 * kLines);
}

}  // namespace
}  // namespace rangex
