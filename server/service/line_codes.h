// Why a line was refused at admission, and why an accepted line was not processed. The
// names are the codes that travel in-band on the ingest stream and in the statistics.
#pragma once
#include <array>
#include <cstddef>
#include <string_view>

namespace rangex {

enum class Refusal {
  kMissingLine,  // the request carried no line
  kUnknownLane,
  kOversized,
  kWrongFrameSize,
  kWrongXraySize,
  kEncoderOutOfRange,  // |encoder| > 2^62
  kCalibrationMismatch,
  kDuplicateLine,     // this count of this lane was already accepted
  kEncoderBackwards,  // behind the lane's latest, never accepted: its slot is already missing
  kOverload,          // the queue is full
  kShuttingDown,      // handed back: resend it to the next server
  kStoreUnavailable,  // handed back: the store cannot write; resend it when it recovers
  kCount
};

enum class DropReason {
  kProcessingError,  // the batch's processing failed; the lane restarted, its fillets fail safe
  kCount
};

constexpr size_t kRefusals = size_t(Refusal::kCount);
constexpr size_t kDropReasons = size_t(DropReason::kCount);

constexpr std::string_view refusal_name(Refusal r) {
  constexpr std::array<std::string_view, kRefusals> names = {"MISSING_LINE",
                                                             "UNKNOWN_LANE",
                                                             "OVERSIZED",
                                                             "WRONG_FRAME_SIZE",
                                                             "WRONG_XRAY_SIZE",
                                                             "ENCODER_OUT_OF_RANGE",
                                                             "CALIBRATION_MISMATCH",
                                                             "DUPLICATE_LINE",
                                                             "ENCODER_BACKWARDS",
                                                             "OVERLOAD",
                                                             "SHUTTING_DOWN",
                                                             "STORE_UNAVAILABLE"};
  return names[size_t(r)];
}

// A line refused with one of these was not lost: the sender keeps it and sends it again.
constexpr bool handed_back(Refusal r) {
  return r == Refusal::kShuttingDown || r == Refusal::kStoreUnavailable;
}

constexpr std::string_view drop_name(DropReason d) {
  constexpr std::array<std::string_view, kDropReasons> names = {"PROCESSING_ERROR"};
  return names[size_t(d)];
}

// Encoder counts the server takes: differences of any two fit in 64 bits.
constexpr int64_t kMaxEncoder = int64_t(1) << 62;

}  // namespace rangex
