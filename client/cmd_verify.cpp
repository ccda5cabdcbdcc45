// rangexctl verify: a verification run on rangexd, each decided fillet held against a
// declared test piece.
#include <grpcpp/grpcpp.h>

#include <cstdio>
#include <string>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "remote_call.h"

namespace rangex::cli {

namespace pb = rangex::v1;

int cmd_verify(int argc, char** argv) {
  const Args a(argc, argv, 2, {},
               remote_options({"lane", "piece", "x-mm", "tolerance-mm", "fillets"}));
  a.expect_positionals(1,
                       "verify start --lane L --piece NAME --x-mm X [--tolerance-mm T] "
                       "[--fillets N]  |  verify list");
  const std::string verb = a.positional(0, "start|list");
  auto stub = pb::ControlService::NewStub(server_channel(a));
  UnaryCall ctx;
  if (verb == "start") {
    pb::StartVerificationRequest req;
    req.set_lane(int(std::stol(a.require("lane"))));
    req.set_piece(a.require("piece"));
    req.set_x_mm(std::stod(a.require("x-mm")));
    req.set_tolerance_mm(std::stod(a.get("tolerance-mm", "0")));
    req.set_fillets(int(std::stol(a.get("fillets", "0"))));
    pb::StartVerificationResponse resp;
    check_status(stub->StartVerification(&ctx, req, &resp), "verify start");
    std::printf("lane %d: verifying '%s': its next %d fillets must show it\n", resp.lane().id(),
                resp.lane().verification().running_piece().c_str(),
                resp.lane().verification().fillets_left());
    return 0;
  }
  if (verb != "list") fail("verify takes start or list (got '", verb, "')");
  pb::ListLanesResponse resp;
  check_status(stub->ListLanes(&ctx, {}, &resp), "lanes");
  for (const auto& l : resp.lanes()) {
    const pb::LaneVerification& v = l.verification();
    std::printf("lane %d: %s%s%s\n", l.id(),
                v.has_last() ? (v.passed() ? "passed: " : "FAILED: ") : "not verified yet",
                v.has_last() ? v.detail().c_str() : "",
                v.running() ? (" (running: " + v.running_piece() + ")").c_str()
                            : (v.overdue() ? " (due)" : ""));
  }
  return 0;
}

}  // namespace rangex::cli
