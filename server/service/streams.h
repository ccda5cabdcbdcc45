// The two streaming RPCs on gRPC's callback API: no thread is held per stream, so the
// server keeps up with many lanes and dashboards on few cores.
//   IngestService.StreamLines: each line read is submitted at once and acknowledged in
//     order; reading pauses while too many acknowledgements wait to be written (a client
//     that does not read its acks is held back by HTTP/2 flow control, not by memory).
//   ResultsService.SubscribeFillets: written as the results hub wakes the stream.
// Each reactor guards its state with its own mutex (taken before the hub's, never held while
// calling the engine or Finish()).
#pragma once
#include <grpcpp/support/server_callback.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "rangex/v1/rangex.pb.h"

namespace rangex {

class Engine;
class ResultsHub;

// An ingest stream as the idle sweep and a newcomer to a full server see it.
class IdleClosable {
 public:
  virtual ~IdleClosable() = default;
  // Finishes the stream (UNAVAILABLE, `why`) when no request came for idle_ns; false when one
  // did, or it is already ending.
  virtual bool close_if_idle(int64_t now_ns, int64_t idle_ns, const std::string& why) = 0;
  virtual int64_t last_request_ns() = 0;  // steady clock; the start when none came
};

// A result subscription as a newcomer sees it when the server holds as many as it may.
class Evictable {
 public:
  virtual ~Evictable() = default;
  virtual uint64_t backlog() = 0;  // results waiting for it (queued and lost)
  virtual void give_way() = 0;     // ends it (RESOURCE_EXHAUSTED), cancelling a pending write
};

struct StreamCounters {
  std::atomic<int> ingest{0}, subscribers{0};
  std::atomic<int> feeding{0};  // ingest streams that have sent a line
  std::mutex live_mu;
  std::vector<std::weak_ptr<IdleClosable>> live;  // open ingest streams (expired: gone)
  std::mutex subs_mu;
  std::vector<std::weak_ptr<Evictable>> subs;  // open subscriptions (expired: gone)
};

// Closes the ingest streams that have had no request for idle_s; returns how many.
int close_idle_ingest_streams(StreamCounters& counters, double idle_s);

// How many ingest streams a server holds, and which gives way when it holds that many.
struct IngestBound {
  int max_streams = 256;    // server.max_ingest_streams
  double gives_way_s = 30;  // server.stream_gives_way_s
};

// A new ingest stream, when the server holds fewer than max_streams, or when one of them has
// had no request for gives_way_s (the one quiet longest gives way: a leaked stream, a feeder
// whose belt stands); else refused with RESOURCE_EXHAUSTED.
grpc::ServerBidiReactor<v1::StreamLinesRequest, v1::StreamLinesResponse>* new_ingest_stream(
    Engine& engine, StreamCounters& counters, const IngestBound& bound);
// A new subscription, when the server holds fewer than max_subscriptions or one of them has
// fallen behind (it gives way); else refused with RESOURCE_EXHAUSTED.
grpc::ServerWriteReactor<v1::SubscribeFilletsResponse>* new_subscription(
    ResultsHub& hub, const v1::SubscribeFilletsRequest& request, StreamCounters& counters,
    grpc::CallbackServerContext* ctx, int max_subscriptions);

// A stream its caller may not open, finished at once with `status`.
grpc::ServerBidiReactor<v1::StreamLinesRequest, v1::StreamLinesResponse>* refused_ingest_stream(
    const grpc::Status& status);
grpc::ServerWriteReactor<v1::SubscribeFilletsResponse>* refused_subscription(
    const grpc::Status& status);

}  // namespace rangex
