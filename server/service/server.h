// rangexd's gRPC server: the four rangex.v1 services over one Engine, with standard health
// checking and server reflection. Start binds the address (port 0 picks a free port).
#pragma once
#include <memory>
#include <string>

#include "core/plant_config.h"
#include "service/engine.h"

namespace grpc {
class Server;
}

namespace rangex {

struct ServerOptions {
  std::string listen;    // host:port; empty takes plant.yaml's
  std::string data_dir;  // empty takes plant.yaml's storage
  EngineOptions engine;
  int max_message_bytes = 64 << 20;  // oversized lines are refused in-band, below this
};

class RangexServer {
 public:
  RangexServer(const PlantConfig& plant, ServerOptions opt);
  ~RangexServer();
  int port() const { return port_; }
  std::string address() const;
  // Graceful: stops taking lines, drains and decides everything queued, flushes the store.
  void shutdown();
  void wait();
  Engine& engine() { return *engine_; }
  Store& store() { return *store_; }

 private:
  struct Services;
  PlantConfig plant_;
  ServerOptions opt_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<ResultsHub> hub_;
  std::unique_ptr<Engine> engine_;
  std::unique_ptr<Services> services_;
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  int64_t started_ns_ = 0;
  bool down_ = false;
};

}  // namespace rangex
