// The results hub: filters, and a slow subscriber loses its oldest results and is told how
// many, without holding anyone up.
#include <gtest/gtest.h>

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
  ASSERT_TRUE(hub.next(slow, 0, f, lagged));
  EXPECT_EQ(lagged, 84u);  // 100 published, 16 kept
  EXPECT_EQ(f.uid, 85);    // the oldest of the kept ones
  ASSERT_TRUE(hub.next(slow, 0, f, lagged));
  EXPECT_EQ(lagged, 0u);  // reported once
  int n = 0;
  while (hub.next(rejects, 0, f, lagged)) {
    EXPECT_EQ(f.decision, "reject");
    ++n;
  }
  EXPECT_EQ(n, 10);
  n = 0;
  while (hub.next(lane2, 0, f, lagged)) {
    EXPECT_EQ(f.lane, 2);
    ++n;
  }
  EXPECT_EQ(n, 25);
  // Once closed (shutdown), an empty subscription ends instead of waiting for more.
  while (hub.next(slow, 0, f, lagged)) {
  }
  hub.close_all();
  EXPECT_FALSE(hub.next(slow, 10000, f, lagged));
  EXPECT_TRUE(slow->closed);
}
