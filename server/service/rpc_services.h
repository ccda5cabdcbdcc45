// rangexd's four gRPC services (rangex.v1: Ingest, Results, Calibration, Control) over the
// engine, the store and the results hub; every call is authorised for the role it needs
// (access_control.h) and a refusal carries the status gRPC defines for it.
#pragma once
#include <cstdint>
#include <memory>

namespace grpc {
class ServerBuilder;
}  // namespace grpc

namespace rangex {

class AccessControl;
class Engine;
class Store;
class ResultsHub;
struct StreamCounters;
struct ServerOptions;

class RpcServices {
 public:
  RpcServices(const AccessControl& access, Engine& engine, Store& store, ResultsHub& hub,
              StreamCounters& counters, const ServerOptions& opt, int64_t started_ns);
  ~RpcServices();
  void register_with(grpc::ServerBuilder& b);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rangex
