#include "plc/release_registers.h"

#include <cstddef>

namespace rangex {

uint16_t release_sequence(int64_t uid) {
  return uint16_t(((uid - 1) % 65535 + 65535) % 65535 + 1);  // never 0: "nothing written"
}

int release_slot(int64_t uid, int ring_slots) {
  return int(((uid % ring_slots) + ring_slots) % ring_slots);
}

SlotRegisters release_registers(const Release& r) {
  const auto lo32 = [](int64_t v) { return uint32_t(uint64_t(v)); };
  SlotRegisters s{};
  s[0] = release_sequence(r.uid);
  s[1] = uint16_t(r.lane);
  s[2] = uint16_t(lo32(r.first_encoder) >> 16);
  s[3] = uint16_t(lo32(r.first_encoder));
  s[4] = uint16_t(lo32(r.last_encoder) >> 16);
  s[5] = uint16_t(lo32(r.last_encoder));
  s[6] = uint16_t(r.code);
  for (int i = 0; i < 7; ++i) s[7] ^= s[std::size_t(i)];
  return s;
}

bool decode_release(const SlotRegisters& s, Release& out, uint16_t& sequence) {
  uint16_t check = 0;
  for (int i = 0; i < 7; ++i) check ^= s[std::size_t(i)];
  if (check != s[7] || s[0] == 0 || s[6] < 1 || s[6] > 4) return false;
  sequence = s[0];
  out.lane = s[1];
  out.first_encoder = int64_t((uint32_t(s[2]) << 16) | s[3]);
  out.last_encoder = int64_t((uint32_t(s[4]) << 16) | s[5]);
  out.code = ReleaseCode(s[6]);
  return true;
}

const char* release_code_name(ReleaseCode c) {
  switch (c) {
    case ReleaseCode::kPass:
      return "pass";
    case ReleaseCode::kReject:
      return "reject";
    case ReleaseCode::kNotInspected:
      return "not_inspected";
    case ReleaseCode::kLate:
      return "late";
  }
  return "?";
}

const char* packml_name(PackMl s) {
  switch (s) {
    case PackMl::kStopped:
      return "stopped";
    case PackMl::kIdle:
      return "idle";
    case PackMl::kExecute:
      return "execute";
    case PackMl::kAborted:
      return "aborted";
    case PackMl::kHeld:
      return "held";
  }
  return "?";
}

}  // namespace rangex
