// The worker's queues: a lane's lines never wait behind another lane's backlog, each lane's
// lines keep their order, and the oldest waiting line is known to the watchdog.
#include <gtest/gtest.h>

#include "service/lane_queues.h"

using namespace rangex;

namespace {
QueuedLine line(int lane, int64_t encoder, int64_t arrived) {
  QueuedLine q;
  q.line.lane = lane;
  q.line.encoder = encoder;
  q.arrived_ns = arrived;
  return q;
}
}  // namespace

TEST(LaneQueues, ALightLaneIsNotHeldBehindAFloodedOne) {
  LaneQueues q(3);
  for (int64_t e = 0; e < 1000; ++e) q.push(0, line(10, e, 100 + e));  // lane 10 floods
  for (int64_t e = 0; e < 3; ++e) q.push(2, line(12, e, 5000 + e));    // lane 12: three lines
  EXPECT_EQ(q.size(), 1003u);
  EXPECT_EQ(q.oldest_arrival_ns(), 100);
  std::vector<QueuedLine> batch;
  q.take(8, batch);
  ASSERT_EQ(batch.size(), 8u);
  // All of lane 12's lines are in the first batch, between lane 10's, each lane in order.
  int64_t next10 = 0, next12 = 0;
  for (const QueuedLine& b : batch) {
    if (b.line.lane == 10) EXPECT_EQ(b.line.encoder, next10++);
    if (b.line.lane == 12) EXPECT_EQ(b.line.encoder, next12++);
  }
  EXPECT_EQ(next12, 3);
  EXPECT_EQ(next10, 5);
  EXPECT_EQ(q.size(), 995u);
  EXPECT_EQ(q.oldest_arrival_ns(), 105);
  // What is left comes out in order, and no more than there is.
  batch.clear();
  q.take(5000, batch);
  ASSERT_EQ(batch.size(), 995u);
  for (const QueuedLine& b : batch) EXPECT_EQ(b.line.encoder, next10++);
  EXPECT_TRUE(q.empty());
  EXPECT_EQ(q.oldest_arrival_ns(), 0);
}

TEST(LaneQueues, TurnsGoOnWhereTheLastBatchEnded) {
  LaneQueues q(2);
  for (int64_t e = 0; e < 4; ++e) {
    q.push(0, line(0, e, 1));
    q.push(1, line(1, e, 1));
  }
  std::vector<QueuedLine> batch;
  for (int k = 0; k < 8; ++k) q.take(1, batch);
  ASSERT_EQ(batch.size(), 8u);
  for (size_t k = 1; k < batch.size(); ++k) EXPECT_NE(batch[k].line.lane, batch[k - 1].line.lane);
}
