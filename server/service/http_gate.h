// The door of rangexd's HTTP side, plain or TLS. cpp-httplib 0.11 gives every connection a pooled
// thread from accept on, and a thread waits as long as its client takes to send the request
// head: forty clients sending a byte every 3 s held every thread and blinded the dashboard.
// The gate waits for request heads itself, all of them on one thread with poll(), and hands
// a connection to a worker only once its whole head has arrived:
// - a head must arrive within head_timeout_s (over TLS the handshake counts in it) (from accept, or
// from the previous answer on a
//   kept-alive connection), and be at most max_head_bytes; otherwise the connection is closed;
// - at most max_waiting connections wait for their heads, and at most max_waiting_per_client
//   from one address; a new one closes the oldest (of its address, when that is over its
//   bound), so slow clients cannot keep a real one out;
// - a small body (at most max_body_bytes) must arrive with its head, within the same time;
// - the workers only ever serve requests that have arrived.
#pragma once
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "service/gate_connection.h"

namespace rangex {

struct GateOptions {
  double head_timeout_s = 10;
  size_t max_waiting = 512;
  size_t max_waiting_per_client = 128;
  size_t max_head_bytes = 64 * 1024;
  // A body up to this size is waited for here with its head (the dashboard's actions send a
  // few hundred bytes of JSON); a larger one is refused by the worker unread.
  size_t max_body_bytes = 16 * 1024;
  int workers = 40;
};

class HttpGate {
 public:
  // serve(connection, head) runs on a worker with the connection's request head; true keeps
  // the connection for the next request (it waits at the gate again).
  using Serve = std::function<bool(GateConnection& c, std::string& head)>;
  HttpGate(GateOptions opt, Serve serve);
  ~HttpGate();
  // A connection accepted (or kept alive) by any thread.
  void admit(std::unique_ptr<GateConnection> c);
  void stop();  // closes every connection waiting; workers finish what they serve

 private:
  struct Waiting {
    std::unique_ptr<GateConnection> conn;
    int64_t since_ns;
    std::string client;  // the peer's address
    short events;        // what the connection waits for
  };
  using Ready = std::pair<std::unique_ptr<GateConnection>, std::string>;
  void poll_loop();
  void worker();

  GateOptions opt_;
  Serve serve_;
  std::string too_large_answer_;
  int wake_[2] = {-1, -1};
  std::mutex mu_;
  std::condition_variable ready_cv_;
  std::deque<Waiting> incoming_;
  std::deque<Ready> ready_;
  bool stop_ = false;
  std::thread poller_;
  std::vector<std::thread> workers_;
};

}  // namespace rangex
