// The results hub: filters, a slow subscriber loses its oldest results and is told how many
// without holding anyone up, and subscribers are woken rather than polling.
#include <gtest/gtest.h>

#include <atomic>

#include "service/results_hub.h"

using namespace rangex;

TEST(ResultsHub, SlowSubscriberIsToldHowMuchItLagged) {
  ResultsHub hub;
  auto slow = hub.subscribe({}, {}, 16);
  auto rejects = hub.subscribe({}, {"reject"}, 1000);
  auto lane2 = hub.subscribe({2}, {}, 1000);
  for (int i = 0; i < 100; ++i) {
    StoredFillet f;
    f.uid = i + 1;
    f.lane = i % 4;
    f.decision = i % 10 == 0 ? "reject" : "pass";
    hub.publish(f);  // never blocks, whatever the subscribers do
  }
  StoredFillet f;
  uint64_t lagged = 0;
  ASSERT_TRUE(hub.take(slow, f, lagged));
  EXPECT_EQ(lagged, 84u);  // 100 published, 16 kept
  EXPECT_EQ(f.uid, 85);    // the oldest of the kept ones
  ASSERT_TRUE(hub.take(slow, f, lagged));
  EXPECT_EQ(lagged, 0u);  // reported once
  int n = 0;
  while (hub.take(rejects, f, lagged)) {
    EXPECT_EQ(f.decision, "reject");
    ++n;
  }
  EXPECT_EQ(n, 10);
  n = 0;
  while (hub.take(lane2, f, lagged)) {
    EXPECT_EQ(f.lane, 2);
    ++n;
  }
  EXPECT_EQ(n, 25);
  // Once closed (shutdown), a drained subscription sees closed instead of waiting for more.
  while (hub.take(slow, f, lagged)) {
  }
  EXPECT_FALSE(hub.closed(slow));
  hub.close_all();
  EXPECT_FALSE(hub.take(slow, f, lagged));
  EXPECT_TRUE(hub.closed(slow));
}

TEST(ResultsHub, SubscribersAreWokenForTheirResultsAndAtClose) {
  ResultsHub hub;
  std::atomic<int> woken_lane1{0}, woken_all{0};
  auto lane1 = hub.subscribe({1}, {}, 8, [&] { ++woken_lane1; });
  auto all = hub.subscribe({}, {}, 8, [&] { ++woken_all; });
  for (int i = 0; i < 6; ++i) {
    StoredFillet f;
    f.lane = i % 3;
    hub.publish(f);
  }
  EXPECT_EQ(woken_lane1, 2);  // only for lane 1's results
  EXPECT_EQ(woken_all, 6);
  hub.close_all();
  EXPECT_EQ(woken_lane1, 3);
  EXPECT_EQ(woken_all, 7);
  // A subscriber arriving after the close is told at once.
  std::atomic<int> late{0};
  auto after = hub.subscribe({}, {}, 8, [&] { ++late; });
  EXPECT_EQ(late, 1);
  EXPECT_TRUE(hub.closed(after));
  hub.unsubscribe(lane1);
  hub.unsubscribe(all);
  hub.unsubscribe(after);
  EXPECT_EQ(hub.subscribers(), 0);
}
