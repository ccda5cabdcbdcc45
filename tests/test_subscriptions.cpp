// Result subscriptions as a plant's network holds them: a server holds at most
// server.max_subscriptions; a client that stopped reading gives way to a new one, and
// clients that keep up are never cut for a newcomer, who is refused instead.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <thread>

#include "core/plant_config.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "server_client.h"
#include "service/results_hub.h"
#include "service/server.h"
#include "temp_dir.h"
#include "wait_until.h"

using namespace rangex;
namespace pb = rangex::v1;

// Named, not anonymous: this file shares a unity batch with other server tests.
namespace subscriptions_test {
using test::TempDir;

ServerOptions options(const TempDir& t, int max_subscriptions) {
  ServerOptions o = test::loopback_options(t.str("data"));
  o.engine.max_subscriptions = max_subscriptions;
  return o;
}

std::chrono::system_clock::time_point bound() {
  return std::chrono::system_clock::now() + std::chrono::seconds(120);  // a hang fails
}

// A subscriber that reads everything as it comes, on a thread of its own.
class Reader {
 public:
  explicit Reader(const std::shared_ptr<grpc::Channel>& ch) {
    ctx_.set_deadline(bound());
    stream_ = pb::ResultsService::NewStub(ch)->SubscribeFillets(&ctx_, {});
    thread_ = std::thread([this] {
      pb::SubscribeFilletsResponse r;
      while (stream_->Read(&r)) ++got_;
      status_ = stream_->Finish();
      ended_ = true;
    });
  }
  ~Reader() {
    ctx_.TryCancel();
    thread_.join();
  }
  int got() const { return got_; }
  bool ended() const { return ended_; }
  const grpc::Status& status() const { return status_; }  // once ended()

 private:
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReader<pb::SubscribeFilletsResponse>> stream_;
  std::thread thread_;
  std::atomic<int> got_{0};
  std::atomic<bool> ended_{false};
  grpc::Status status_;
};

StoredFillet result(int64_t uid) {
  StoredFillet f;
  f.uid = uid;
  f.decision = "pass";
  f.reason = std::string(1000, 'r');  // as big as a fillet's with a few fragments
  return f;
}

}  // namespace subscriptions_test

TEST(Subscriptions, OneThatStoppedReadingGivesWayAndOnesThatKeepUpAreNeverCut) {
  namespace subs = subscriptions_test;
  using test::connect;
  using test::wait_until;
  test::TempDir t;
  RangexServer server(load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml"),
                      subs::options(t, 3));
  auto ch = connect(server);
  auto a = std::make_unique<subs::Reader>(ch);
  auto b = std::make_unique<subs::Reader>(ch);
  auto c = std::make_unique<subs::Reader>(ch);
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().subscribers() == 3; }));

  // Full, and all three keep up: a newcomer is refused, naming the bound.
  {
    subs::Reader d(ch);
    ASSERT_TRUE(wait_until(60, [&] { return d.ended(); }));
    EXPECT_EQ(d.status().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(d.status().error_message().find("server.max_subscriptions"), std::string::npos)
        << d.status().error_message();
  }

  // One place goes to a client that never reads (its own connection, as a dashboard's).
  c.reset();
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().subscribers() == 2; }));
  // Its HTTP/2 window stays at 64 kB (no BDP probes), so that its backlog grows within a
  // test's results: a client's window only puts it off.
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  auto deaf_ch =
      grpc::CreateCustomChannel(server.address(), grpc::InsecureChannelCredentials(), args);
  grpc::ClientContext deaf_ctx;
  deaf_ctx.set_deadline(subs::bound());
  auto deaf = pb::ResultsService::NewStub(deaf_ch)->SubscribeFillets(&deaf_ctx, {});
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().subscribers() == 3; }));

  // Results it does not read: more than its HTTP/2 window and its queue of 256 hold. They
  // come in bursts that the readers take whole (a burst over 256 would lose them some).
  constexpr int kResults = 3000, kBurst = 50;
  for (int i = 1; i <= kResults; ++i) {
    server.hub().publish(subs::result(i));
    if (i % kBurst == 0)
      ASSERT_TRUE(wait_until(60, [&] { return a->got() == i && b->got() == i; }))
          << a->got() << ", " << b->got() << " of " << i;
  }

  // Full again: the one that stopped reading gives way, and the newcomer gets its results.
  subs::Reader e(ch);
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().dropped() == 1; }));
  auto drained = std::async(std::launch::async, [&] {
    pb::SubscribeFilletsResponse r;
    while (deaf->Read(&r)) {
    }
    return deaf->Finish();
  });
  ASSERT_EQ(drained.wait_for(std::chrono::seconds(60)), std::future_status::ready)
      << "the stream that gave way was not ended";
  EXPECT_FALSE(drained.get().ok());
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().subscribers() == 3; }));
  for (int i = 1; i <= 10; ++i) server.hub().publish(subs::result(kResults + i));
  EXPECT_TRUE(wait_until(
      60, [&] { return a->got() == kResults + 10 && b->got() == kResults + 10 && e.got() == 10; }))
      << a->got() << ", " << b->got() << ", " << e.got();
  EXPECT_FALSE(a->ended());
  EXPECT_FALSE(b->ended());

  // The three left keep up: the next newcomer is refused, and statistics count the one drop.
  {
    subs::Reader f(ch);
    ASSERT_TRUE(wait_until(60, [&] { return f.ended(); }));
    EXPECT_EQ(f.status().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  }
  grpc::ClientContext sctx;
  sctx.set_deadline(subs::bound());
  pb::GetStatisticsResponse st;
  ASSERT_TRUE(pb::ControlService::NewStub(ch)->GetStatistics(&sctx, {}, &st).ok());
  EXPECT_EQ(st.subscribers_dropped(), 1u);
  EXPECT_EQ(st.subscribers(), 3);
  a.reset();
  b.reset();
  server.shutdown();
}
