// rangexctl record start|stop|status: a shift recording on rangexd, every accepted line
// copied into a bounded recording.
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

namespace {

void print_recording(const pb::RecordingStatus& r) {
  std::string lanes;
  for (int l : r.lanes()) lanes.append(lanes.empty() ? "" : ",").append(std::to_string(l));
  std::printf(
      "recording %s (lanes %s, %.1f minutes) %s: %llu lines, %llu MB of %llu MB, %llu "
      "left out%s%s\n  %s\n",
      r.name().c_str(), lanes.c_str(), r.minutes(), r.active() ? "running" : "ended",
      (unsigned long long)r.lines(), (unsigned long long)(r.bytes() >> 20),
      (unsigned long long)(r.budget_bytes() >> 20), (unsigned long long)r.left_out(),
      r.ended().empty() ? "" : "; ", r.ended().c_str(), r.dir().c_str());
}

}  // namespace

int cmd_record(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, remote_options({"lanes", "minutes", "name"}));
  a.expect_positionals(1,
                       "record start [--lanes 0,1] --minutes N [--name NAME]  |  record stop  "
                       "|  record status");
  const std::string verb = a.positional(0, "start|stop|status");
  auto stub = pb::ControlService::NewStub(server_channel(a));
  UnaryCall ctx;
  if (verb == "start") {
    pb::StartRecordingRequest req;
    // Lane ids from 0 (the server names one it does not have).
    for (int lane : a.lane_ids("lanes")) req.add_lanes(lane);
    req.set_minutes(std::stod(a.require("minutes")));
    req.set_name(a.get("name", ""));
    pb::StartRecordingResponse resp;
    check_status(stub->StartRecording(&ctx, req, &resp), "record start");
    print_recording(resp.recording());
    return 0;
  }
  if (verb == "stop") {
    pb::StopRecordingResponse resp;
    check_status(stub->StopRecording(&ctx, {}, &resp), "record stop");
    print_recording(resp.recording());
    std::printf("replay it: rangexctl process %s/laneL --out DIR\n",
                resp.recording().dir().c_str());
    return 0;
  }
  if (verb == "status") {
    pb::GetStatisticsResponse s;
    check_status(stub->GetStatistics(&ctx, {}, &s), "statistics");
    if (!s.has_recording()) {
      std::printf("no recording since the server started\n");
      return 0;
    }
    print_recording(s.recording());
    return 0;
  }
  fail("record takes start, stop or status (got '", verb, "')");
}

}  // namespace rangex::cli
