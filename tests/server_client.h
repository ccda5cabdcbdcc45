// A plain client of the server for the tests: a channel, one ingest stream sent in order,
// the lines of a recording as the plant would send them, every decision stored.
#pragma once
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "core/plant_config.h"
#include "core/recording.h"
#include "rangex/v1/rangex.grpc.pb.h"
#include "service/server.h"
#include "store/store.h"

namespace rangex::test {

namespace pb = rangex::v1;

// A server on a free loopback port, storing under data_dir, on the CPU backend's one thread.
inline ServerOptions loopback_options(const std::string& data_dir) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = data_dir;
  o.engine.backend = cpu_request(1);
  return o;
}

inline std::shared_ptr<grpc::Channel> connect(const RangexServer& s) {
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(64 << 20);
  return grpc::CreateCustomChannel(s.address(), grpc::InsecureChannelCredentials(), args);
}

inline  // Streams lines, returns the acks in order.
    std::vector<pb::StreamLinesResponse>
    stream(const std::shared_ptr<grpc::Channel>& ch, const std::vector<pb::LineScan>& lines) {
  auto stub = pb::IngestService::NewStub(ch);
  grpc::ClientContext ctx;
  auto s = stub->StreamLines(&ctx);
  std::vector<pb::StreamLinesResponse> acks;
  std::thread reader([&] {
    pb::StreamLinesResponse r;
    while (s->Read(&r)) acks.push_back(r);
  });
  uint64_t seq = 0;
  for (const auto& l : lines) {
    pb::StreamLinesRequest req;
    req.set_sequence(seq++);
    *req.mutable_line() = l;
    if (!s->Write(req)) break;
  }
  s->WritesDone();
  reader.join();
  EXPECT_TRUE(s->Finish().ok());
  return acks;
}

inline std::vector<StoredFillet> all_fillets(Store& st) {
  return st.list_fillets(0, 0, -1, 0, 100000);
}

// Every line of a recording, lanes interleaved line by line as a plant's lanes arrive.
inline std::vector<pb::LineScan> recording_lines(const RecordingReader& rec, const PlantConfig& p) {
  std::vector<pb::LineScan> lines;
  for (int64_t n = 0; n < rec.info().lines; ++n)
    for (int lane : rec.info().lanes) {
      const LaneConfig& lc = p.lane(lane);
      const size_t frame = size_t(lc.frame_width) * lc.frame_height;
      pb::LineScan l;
      std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(lc.xray.pixels) * 2, '\0');
      int64_t enc;
      rec.read(lane, n, 1, reinterpret_cast<uint8_t*>(c0.data()),
               reinterpret_cast<uint8_t*>(c1.data()), reinterpret_cast<uint16_t*>(x.data()), &enc);
      l.set_lane(lane);
      l.set_encoder(enc);
      l.set_cam0(std::move(c0));
      l.set_cam1(std::move(c1));
      l.set_xray(std::move(x));
      l.set_calibration_id(rec.info().calibration_id);
      lines.push_back(std::move(l));
    }
  return lines;
}

}  // namespace rangex::test
