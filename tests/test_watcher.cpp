// `rangexctl watch`'s subscriber (client/watcher): every decision once, in the store's order,
// when its stream skipped some and when decisions were made while it had no server. Its
// reconnects through stops and crashes of rangexd mid-feed are checked by crash_test.py
// (stop_consistency, crash_consistency).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/plant_config.h"
#include "server_client.h"
#include "service/results_hub.h"
#include "service/server.h"
#include "store/store.h"
#include "temp_dir.h"
#include "wait_until.h"
#include "watcher.h"

using namespace rangex;
namespace pb = rangex::v1;

// Named, not anonymous: a unity batch may hold other tests' helpers.
namespace watcher_test {

// Stored, then published, as the recorder does; the published uid is the store's.
void decide(Store& store, ResultsHub* hub, int i) {
  StoredFillet f;
  f.lane_fillet = i;
  f.decision = "pass";
  f.reason = std::string(1000, 'r');  // as big as a fillet's with a few fragments
  f.decided_ns = now_ns();
  f.uid = store.add_fillet(f);
  if (hub) hub->publish(f);
}

std::vector<int64_t> one_to(int n) {
  std::vector<int64_t> v(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) v[size_t(i)] = i + 1;
  return v;
}

}  // namespace watcher_test

// The watcher reads too slowly for a while: the server skips what the subscription's queue
// cannot hold and says how many (lagged). The watcher takes the skipped ones from the store.
TEST(Watcher, OneThatFellBehindTakesWhatWasSkippedFromTheStore) {
  using test::wait_until;
  test::TempDir t;
  RangexServer server(load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml"),
                      test::loopback_options(t.str("data")));
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);  // a 64 kB window: the backlog is the server's
  auto ch = grpc::CreateCustomChannel(server.address(), grpc::InsecureChannelCredentials(), args);

  constexpr int kDecisions = 800;  // more than the queue (256) and the window hold
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> shown{0};
  std::vector<int64_t> uids;
  WatchOptions wo;
  wo.count = kDecisions;
  wo.until = std::chrono::system_clock::now() + std::chrono::seconds(120);  // a hang fails
  wo.show = [&](const pb::FilletResult& f) {
    uids.push_back(f.uid());
    if (++shown == 1) released.wait();  // stops reading after the first
  };
  auto run = std::async(std::launch::async, [&] { return Watcher(ch, wo).run(); });
  ASSERT_TRUE(wait_until(60, [&] { return server.hub().subscribers() == 1; }));

  watcher_test::decide(server.store(), &server.hub(), 1);
  ASSERT_TRUE(wait_until(60, [&] { return shown == 1; }));
  for (int i = 2; i <= kDecisions; ++i) watcher_test::decide(server.store(), &server.hub(), i);
  release.set_value();

  ASSERT_EQ(run.wait_for(std::chrono::seconds(150)), std::future_status::ready)
      << "the watcher showed " << shown << " of " << kDecisions;
  const WatchReport r = run.get();
  EXPECT_TRUE(r.status.ok()) << r.status.error_message();
  EXPECT_EQ(r.shown, uint64_t(kDecisions));
  EXPECT_GT(r.filled, 0u) << "the stream skipped nothing: the fill was not tested";
  EXPECT_EQ(r.reconnects, 0u);
  EXPECT_EQ(uids, watcher_test::one_to(kDecisions));
  server.shutdown();
}

// The server goes away; while it is away decisions reach its store (here written to it
// directly); another server comes up on the same store and port. The watcher connects again
// and shows those from the store before the new server's own.
TEST(Watcher, OneWhoseServerWentAwayTakesWhatWasDecidedMeanwhile) {
  using test::wait_until;
  test::TempDir t;
  const PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  ServerOptions o = test::loopback_options(t.str("data"));
  auto server = std::make_unique<RangexServer>(plant, o);
  o.listen = server->address();  // the next one on the same port

  std::mutex mu;
  std::vector<int64_t> uids;
  WatchOptions wo;
  wo.count = 9;
  wo.until = std::chrono::system_clock::now() + std::chrono::seconds(120);  // a hang fails
  wo.show = [&](const pb::FilletResult& f) {
    std::lock_guard<std::mutex> lk(mu);
    uids.push_back(f.uid());
  };
  auto shown = [&] {
    std::lock_guard<std::mutex> lk(mu);
    return uids.size();
  };
  auto run =
      std::async(std::launch::async, [&] { return Watcher(test::connect(*server), wo).run(); });
  ASSERT_TRUE(wait_until(60, [&] { return server->hub().subscribers() == 1; }));
  for (int i = 1; i <= 3; ++i) watcher_test::decide(server->store(), &server->hub(), i);
  ASSERT_TRUE(wait_until(60, [&] { return shown() == 3; }));

  server.reset();
  {
    Store store(o.data_dir);
    for (int i = 4; i <= 7; ++i) watcher_test::decide(store, nullptr, i);
  }
  server = std::make_unique<RangexServer>(plant, o);
  ASSERT_TRUE(wait_until(60, [&] { return server->hub().subscribers() == 1; }))
      << "the watcher did not subscribe to the next server";
  for (int i = 8; i <= 9; ++i) watcher_test::decide(server->store(), &server->hub(), i);

  ASSERT_EQ(run.wait_for(std::chrono::seconds(150)), std::future_status::ready)
      << "the watcher showed " << shown() << " of 9";
  const WatchReport r = run.get();
  EXPECT_TRUE(r.status.ok()) << r.status.error_message();
  EXPECT_EQ(r.shown, 9u);
  // The four from the store; the next server's two may be too, if they were stored before the
  // watcher's fill asked.
  EXPECT_GE(r.filled, 4u);
  EXPECT_GE(r.reconnects, 1u);
  EXPECT_EQ(uids, watcher_test::one_to(9));
  server->shutdown();
}
