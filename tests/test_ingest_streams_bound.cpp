// Ingest streams as a plant's network holds them: a server holds at most
// server.max_ingest_streams (each costs it about 20 kB); one past it is refused naming the
// bound, the streams it holds go on, and a place that ends is taken by the next.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <thread>

#include "core/plant_config.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "server_client.h"
#include "service/server.h"
#include "temp_dir.h"
#include "wait_until.h"

using namespace rangex;
namespace pb = rangex::v1;

// Named, not anonymous: this file shares a unity batch with other server tests.
namespace ingest_bound_test {

// An ingest stream that has asked for its credit once: open when it was answered.
class Feed {
 public:
  explicit Feed(const std::shared_ptr<grpc::Channel>& ch) {
    ctx_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    stream_ = pb::IngestService::NewStub(ch)->StreamLines(&ctx_);
    pb::StreamLinesRequest q;
    q.set_sequence(1);
    q.set_credit_query(true);
    pb::StreamLinesResponse r;
    answered_ = stream_->Write(q) && stream_->Read(&r) && r.sequence() == 1 && r.credit() > 0;
  }
  bool answered() const { return answered_; }
  bool ask(int sequence) {  // another request for credit: the stream is not quiet
    pb::StreamLinesRequest q;
    q.set_sequence(sequence);
    q.set_credit_query(true);
    pb::StreamLinesResponse r;
    return stream_->Write(q) && stream_->Read(&r) && r.sequence() == sequence;
  }
  grpc::Status end() {  // ends it from the client's side; the server's status
    stream_->WritesDone();
    pb::StreamLinesResponse r;
    while (stream_->Read(&r)) {
    }
    return stream_->Finish();
  }

 private:
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReaderWriter<pb::StreamLinesRequest, pb::StreamLinesResponse>>
      stream_;
  bool answered_ = false;
};

}  // namespace ingest_bound_test

TEST(IngestStreamsBound, OnePastTheBoundIsRefusedAndTheNextTakesAPlaceThatEnds) {
  using ingest_bound_test::Feed;
  test::TempDir t;
  ServerOptions o = test::loopback_options(t.str("data"));
  o.engine.max_ingest_streams = 2;
  RangexServer server(load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml"), o);
  auto ch = test::connect(server);

  Feed a(ch), b(ch);
  ASSERT_TRUE(a.answered() && b.answered());
  EXPECT_EQ(server.ingest_streams(), 2);
  {
    // Full: a third is refused, naming the bound (on its own connection, as a feeder's).
    auto other = grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());
    Feed c(other);
    EXPECT_FALSE(c.answered());
    const grpc::Status s = c.end();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(s.error_message().find("too many ingest streams (2, server.max_ingest_streams)"),
              std::string::npos)
        << s.error_message();
  }
  EXPECT_EQ(server.ingest_streams(), 2);  // the two it holds go on

  // One ends: its place goes to the next.
  EXPECT_TRUE(a.end().ok());
  ASSERT_TRUE(test::wait_until(60, [&] { return server.ingest_streams() == 1; }));
  Feed d(ch);
  EXPECT_TRUE(d.answered());
  EXPECT_EQ(server.ingest_streams(), 2);
  EXPECT_TRUE(b.end().ok());
  EXPECT_TRUE(d.end().ok());
}

// Streams a feeder leaked (opened and never used) fill the server: a feeder's new stream then
// takes the place of the one quiet longest, once it has been quiet for
// server.stream_gives_way_s, and not before. A stream that asks is never cut for it.
TEST(IngestStreamsBound, TheStreamQuietLongestGivesWayToANewOne) {
  using ingest_bound_test::Feed;
  test::TempDir t;
  ServerOptions o = test::loopback_options(t.str("data"));
  o.engine.max_ingest_streams = 2;
  o.engine.stream_gives_way_s = 2;
  RangexServer server(load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml"), o);
  auto ch = test::connect(server);
  auto other = grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());

  Feed leaked(ch), feeding(ch);
  ASSERT_TRUE(leaked.answered() && feeding.answered());
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  ASSERT_TRUE(feeding.ask(2));  // the other stays quiet
  Feed next(other);
  EXPECT_TRUE(next.answered()) << "the quiet stream did not give way";
  const grpc::Status gone = leaked.end();
  EXPECT_EQ(gone.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(gone.error_message().find("no request for 2 s while the server held its 2 ingest "
                                      "streams (server.max_ingest_streams): closed for a new one"),
            std::string::npos)
      << gone.error_message();
  ASSERT_TRUE(test::wait_until(60, [&] { return server.ingest_streams() == 2; }));
  {
    // Both have just asked: none gives way, and a fourth is refused naming both settings.
    ASSERT_TRUE(feeding.ask(3) && next.ask(2));
    Feed refused(other);
    EXPECT_FALSE(refused.answered());
    const grpc::Status s = refused.end();
    EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(s.error_message().find("too many ingest streams (2, server.max_ingest_streams), "
                                     "none without a request for 2 s"),
              std::string::npos)
        << s.error_message();
  }
  EXPECT_TRUE(feeding.ask(4));
  EXPECT_TRUE(feeding.end().ok());
  EXPECT_TRUE(next.end().ok());
}
