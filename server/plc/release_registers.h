// What rangex writes into the PLC's holding registers (docs/plc.md): a fillet's release as
// one ring slot of eight registers, and each lane's state in the PackML manner. Pure values:
// the simulated PLC of the tests decodes with the same layout, and a PLC programmer reads it
// from docs/plc.md.
#pragma once
#include <array>
#include <cstdint>

namespace rangex {

enum class ReleaseCode : uint16_t {
  kPass = 1,          // released: the gate lets it through
  kReject = 2,        // bone found: diverted
  kNotInspected = 3,  // could not be inspected: diverted
  kLate = 4,          // clean, but decided after its deadline: diverted
};

struct Release {
  int64_t uid = 0;  // the fillet's record number in the store (unique, rising across restarts)
  int lane = 0;
  int64_t first_encoder = 0, last_encoder = 0;  // the fillet's X-ray lines
  ReleaseCode code = ReleaseCode::kNotInspected;
};

// Slot registers: [0] sequence, [1] lane, [2..3] first encoder (low 32 bits, high word first),
// [4..5] last encoder, [6] code, [7] check (XOR of [0..6]). The sequence is written last.
constexpr int kSlotRegisters = 8;
using SlotRegisters = std::array<uint16_t, kSlotRegisters>;

uint16_t release_sequence(int64_t uid);         // 1..65535, rising with the uid
int release_slot(int64_t uid, int ring_slots);  // where it goes in the ring
SlotRegisters release_registers(const Release& r);
// The release a slot holds, or false when its check fails (a slot being written).
bool decode_release(const SlotRegisters& regs, Release& out, uint16_t& sequence);

// PackML states (ISA-TR88.00.02 numbering) and why.
enum class PackMl : uint16_t { kStopped = 2, kIdle = 4, kExecute = 6, kAborted = 9, kHeld = 11 };
enum class StateReason : uint16_t {
  kNone = 0,
  kNotFed = 1,        // no line for a while, or never
  kSensorLost = 2,    // a camera or the X-ray detector is not streaming
  kStoreFailing = 3,  // decisions cannot be stored
  kStopping = 4,      // rangexd is stopping
};
const char* packml_name(PackMl s);
const char* release_code_name(ReleaseCode c);  // pass, reject, not_inspected, late

}  // namespace rangex
