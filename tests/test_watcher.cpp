// `rangexctl watch`'s subscriber (client/watcher): every decision once, in the store's order,
// when its stream skipped some. Its reconnects through stops and crashes are checked by
// crash_test.py (stop_consistency, crash_consistency).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
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

  auto decide = [&](int i) {  // as the recorder does: stored, then published
    StoredFillet f;
    f.lane_fillet = i;
    f.decision = "pass";
    f.reason = std::string(1000, 'r');  // as big as a fillet's with a few fragments
    f.decided_ns = now_ns();
    f.uid = server.store().add_fillet(f);
    server.hub().publish(f);
  };
  decide(1);
  ASSERT_TRUE(wait_until(60, [&] { return shown == 1; }));
  for (int i = 2; i <= kDecisions; ++i) decide(i);
  release.set_value();

  ASSERT_EQ(run.wait_for(std::chrono::seconds(150)), std::future_status::ready)
      << "the watcher showed " << shown << " of " << kDecisions;
  const WatchReport r = run.get();
  EXPECT_TRUE(r.status.ok()) << r.status.error_message();
  EXPECT_EQ(r.shown, uint64_t(kDecisions));
  EXPECT_GT(r.filled, 0u) << "the stream skipped nothing: the fill was not tested";
  EXPECT_EQ(r.reconnects, 0u);
  std::vector<int64_t> want(kDecisions);
  for (int i = 0; i < kDecisions; ++i) want[i] = i + 1;
  EXPECT_EQ(uids, want);
  server.shutdown();
}
