// A subscriber to rangexd's decisions that loses none: when its stream ends (the server
// stopped or restarted, the network dropped, it fell behind and gave way), it connects again
// and takes what was decided meanwhile from the store (ListFillets), each decision shown once,
// in the order of the store.
#pragma once
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "rangex/v1/rangex.pb.h"

namespace rangex {

struct WatchOptions {
  v1::SubscribeFilletsRequest filter;  // lanes and decisions (empty: all)
  uint64_t count = 0;                  // stop after this many shown (0: never)
  std::optional<std::chrono::system_clock::time_point> until;  // stop then
  double reconnect_for_s = 60;  // without a stream this long, give up (0: at the first loss)
  std::function<void(const v1::FilletResult&)> show;
  std::function<void(const std::string&)> log;  // reconnects and fills, for stderr
};

struct WatchReport {
  uint64_t shown = 0;       // decisions shown, filled ones included
  uint64_t filled = 0;      // of them, taken from the store after a loss or a lag
  uint64_t reconnects = 0;  // streams opened again
  grpc::Status status;      // OK, or why the watch ended early
};

class Watcher {
 public:
  Watcher(std::shared_ptr<grpc::Channel> channel, WatchOptions opt);
  // Until count, until, a refusal, or no stream for reconnect_for_s.
  WatchReport run();

 private:
  struct State;
  bool begin(State& st);
  bool fill(State& st, int64_t below_uid, WatchReport& rep);
  bool show(State& st, const v1::FilletResult& f, WatchReport& rep);
  bool wanted(const v1::FilletResult& f) const;

  std::shared_ptr<grpc::Channel> channel_;
  WatchOptions opt_;
};

}  // namespace rangex
