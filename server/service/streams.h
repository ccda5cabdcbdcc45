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

#include "rangex/v1/rangex.pb.h"

namespace rangex {

class Engine;
class ResultsHub;

struct StreamCounters {
  std::atomic<int> ingest{0}, subscribers{0};
  std::atomic<int> feeding{0};  // ingest streams that have sent a line
};

grpc::ServerBidiReactor<v1::StreamLinesRequest, v1::StreamLinesResponse>* new_ingest_stream(
    Engine& engine, StreamCounters& counters);
grpc::ServerWriteReactor<v1::SubscribeFilletsResponse>* new_subscription(
    ResultsHub& hub, const v1::SubscribeFilletsRequest& request, StreamCounters& counters);

// A stream its caller may not open, finished at once with `status`.
grpc::ServerBidiReactor<v1::StreamLinesRequest, v1::StreamLinesResponse>* refused_ingest_stream(
    const grpc::Status& status);
grpc::ServerWriteReactor<v1::SubscribeFilletsResponse>* refused_subscription(
    const grpc::Status& status);

}  // namespace rangex
