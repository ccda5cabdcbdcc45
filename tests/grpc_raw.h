// Raw gRPC calls for the server tests, for services with no generated code here
// (grpc.health.v1): one unary call through the generic stub, and a health check.
#pragma once
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <string>
#include <vector>

namespace rangex::test {

inline grpc::Status generic_unary(const std::shared_ptr<grpc::Channel>& ch,
                                  const std::string& method, const std::string& request,
                                  std::string& response) {
  grpc::GenericStub stub(ch);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  grpc::CompletionQueue cq;
  grpc::Slice slice(request);
  grpc::ByteBuffer req(&slice, 1), resp;
  auto call = stub.PrepareUnaryCall(&ctx, method, req, &cq);
  call->StartCall();
  grpc::Status status;
  call->Finish(&resp, &status, reinterpret_cast<void*>(1));
  void* tag;
  bool ok;
  cq.Next(&tag, &ok);
  std::vector<grpc::Slice> slices;
  if (status.ok()) {
    resp.Dump(&slices);
    for (auto& s : slices) response.append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
  return status;
}

// grpc.health.v1.Health/Check of `service` ("" for the whole server): 1 SERVING,
// 2 NOT_SERVING, or minus the status code of a failed call (-5: NOT_FOUND).
inline int health(const std::shared_ptr<grpc::Channel>& ch, const std::string& service) {
  std::string req;
  if (!service.empty()) req = std::string("\x0a", 1) + char(service.size()) + service;
  std::string resp;
  const grpc::Status s = generic_unary(ch, "/grpc.health.v1.Health/Check", req, resp);
  if (!s.ok()) return -int(s.error_code());
  return resp.size() == 2 && resp[0] == '\x08' ? int(resp[1]) : 0;  // 0: UNKNOWN
}

}  // namespace rangex::test
