// One camera's stripes of a recorded lane, extracted batch by batch (64 frames read at a
// time from the recording): what `rangexctl extract` writes and what the calibration solvers
// read from a scan.
#pragma once
#include <cstdint>
#include <functional>

#include "core/recording.h"
#include "pipeline/stripe_extract.h"

namespace rangex {

// `each` sees every batch: its first line, its line count and the stripes of its frames.
void for_each_recorded_stripe_batch(
    const RecordingReader& rec, int lane, int cam, const StripeSlot& slot,
    const std::function<void(int64_t first, int count, const StripeOutput& stripes)>& each);

}  // namespace rangex
