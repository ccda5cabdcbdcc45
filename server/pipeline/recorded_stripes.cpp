#include "pipeline/recorded_stripes.h"

#include <algorithm>
#include <vector>

namespace rangex {

void for_each_recorded_stripe_batch(
    const RecordingReader& rec, int lane, int cam, const StripeSlot& slot,
    const std::function<void(int64_t first, int count, const StripeOutput& stripes)>& each) {
  const RecordingInfo& info = rec.info();
  const int W = info.width, H = info.height;
  constexpr int kBatch = 64;
  std::vector<uint8_t> frames(size_t(W) * H * kBatch);
  std::vector<int> slots(kBatch, 0);
  StripeOutput so;
  for (int64_t n0 = 0; n0 < info.lines; n0 += kBatch) {
    const int count = int(std::min<int64_t>(kBatch, info.lines - n0));
    rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
             cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
    extract_stripes(frames.data(), count, W, H, slots.data(), &slot, so);
    each(n0, count, so);
  }
}

}  // namespace rangex
