// LineScan requests through admission as a hostile or broken feeder could send them: the
// protobuf parse of each StreamLinesRequest, the line's shape against its lane's (frame and
// X-ray sizes, the encoder's range) and the lane's count admission (duplicates, counts going
// back, encoder resets), checked against a model of what each lane has taken:
//   - a line passes the shape check only with exactly its lane's sizes and |encoder| <= 2^62;
//   - a count is never taken twice while within the window; a duplicate is one taken before;
//   - without a restart, taken counts only increase.
// Input: requests in FuzzedDataProvider's random-length string encoding, each a serialised
// StreamLinesRequest (tests/fuzz/make_seeds.py writes the seeds).
#include <fuzzer/FuzzedDataProvider.h>

#include <cstdlib>
#include <map>
#include <set>

#include "rangex/v1/rangex.pb.h"
#include "service/lane_admission.h"
#include "service/line_from_proto.h"
#include "service/line_shape.h"

using namespace rangex;

namespace {
constexpr int kWindow = 256;
const std::map<int, LaneShape> kLanes = {{0, {0, 8, 4, 6}}, {3, {3, 16, 2, 4}}};

struct Model {
  LaneAdmission admission;
  std::set<int64_t> taken;  // since the last restart
  bool fed = false;
  int64_t last = 0;
};
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  std::map<int, Model> lanes;
  for (const auto& [id, shape] : kLanes)
    lanes.emplace(id, Model{LaneAdmission(id, kWindow, true), {}, false, 0});
  for (int k = 0; k < 64 && in.remaining_bytes() > 0; ++k) {
    v1::StreamLinesRequest req;
    if (!req.ParseFromString(in.ConsumeRandomLengthString(4096)) || !req.has_line()) continue;
    const IncomingLine line = take_line(*req.mutable_line());
    const auto lane = kLanes.find(line.lane);
    if (lane == kLanes.end()) continue;  // UNKNOWN_LANE
    const LaneShape& s = lane->second;
    if (check_line_shape(s, line)) continue;  // refused, with a message
    if (line.cam0.size() != size_t(s.width * s.height) || line.cam1.size() != line.cam0.size() ||
        line.xray.size() != size_t(s.pixels) * 2 || line.encoder > kMaxEncoder ||
        line.encoder < -kMaxEncoder)
      std::abort();  // a misshapen line got through
    Model& m = lanes.at(line.lane);
    const LaneAdmission::Verdict v = m.admission.check(line.encoder);
    const bool within = m.fed && line.encoder <= m.last &&
                        uint64_t(m.last) - uint64_t(line.encoder) < uint64_t(kWindow);
    if (v.outcome == LaneAdmission::Outcome::kDuplicate && !m.taken.count(line.encoder))
      std::abort();  // called a duplicate, never taken
    if (v.outcome == LaneAdmission::Outcome::kAccept) {
      const bool restart = !v.restart.empty();
      if (!restart && within && m.taken.count(line.encoder)) std::abort();  // taken twice
      if (!restart && m.fed && line.encoder <= m.last) std::abort();        // went back
      m.admission.commit(line.encoder, restart);
      if (restart) m.taken.clear();
      m.taken.insert(line.encoder);
      m.fed = true;
      m.last = line.encoder;
      if (m.admission.check(line.encoder).outcome != LaneAdmission::Outcome::kDuplicate)
        std::abort();  // a resend of what was just taken must be a duplicate
    }
  }
  return 0;
}
