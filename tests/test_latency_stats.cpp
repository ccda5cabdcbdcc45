// A stage's latency: percentiles of the recent samples and a cumulative histogram of all.
#include <gtest/gtest.h>

#include "service/latency_stats.h"

using namespace rangex;

TEST(LatencyStats, HistogramCountsEverySampleAtItsBound) {
  LatencyStats s;
  // 0.5 ms lands in the first bucket (<= 0.5), 0.51 in the second, 20000 only in +Inf.
  for (double ms : {0.5, 0.51, 3.0, 3.0, 50.0, 20000.0}) s.add(ms);
  const LatencyStats::Summary r = s.summary();
  EXPECT_EQ(r.samples, 6u);
  EXPECT_DOUBLE_EQ(r.sum_ms, 0.5 + 0.51 + 3 + 3 + 50 + 20000);
  const auto& b = LatencyStats::kBoundsMs;
  for (size_t k = 0; k < b.size(); ++k) {
    uint64_t want = 0;
    for (double ms : {0.5, 0.51, 3.0, 3.0, 50.0, 20000.0}) want += ms <= b[k];
    EXPECT_EQ(r.cumulative[k], want) << "le " << b[k];
  }
  EXPECT_DOUBLE_EQ(r.p50, 3.0);
  EXPECT_DOUBLE_EQ(r.p99, 20000.0);
}

TEST(LatencyStats, PercentilesFollowTheRecentSamplesAndTheHistogramKeepsAll) {
  LatencyStats s;
  for (int k = 0; k < 5000; ++k) s.add(100.0);
  for (int k = 0; k < 4096; ++k) s.add(1.0);  // the ring now holds only these
  const LatencyStats::Summary r = s.summary();
  EXPECT_DOUBLE_EQ(r.p99, 1.0);
  EXPECT_EQ(r.samples, 9096u);
  EXPECT_EQ(r.cumulative[1], 4096u);      // <= 1 ms
  EXPECT_EQ(r.cumulative.back(), 9096u);  // <= 10 s
  EXPECT_DOUBLE_EQ(r.sum_ms, 5000 * 100.0 + 4096 * 1.0);
}
