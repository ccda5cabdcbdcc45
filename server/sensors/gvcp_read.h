// One read of a GigE Vision device's memory over GVCP (UDP port 3956), without Aravis: what a
// device names as its GenICam description is read this way before Aravis is given it
// (genicam_url.h). Any host may read; no control of the device is taken.
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

constexpr uint32_t kGvcpXmlUrl0 = 0x200;  // the first URL register, 512 bytes
constexpr uint16_t kGvcpReadMax = 512;    // bytes one READMEM may ask for

// `count` bytes (a multiple of 4, at most kGvcpReadMax) at `address` of the device at `ipv4`.
// Each try waits `timeout_ms` for the answer. Throws Error naming the device and what failed:
// no answer, an error status, an answer to another request.
std::string gvcp_read_memory(const std::string& ipv4, uint32_t address, uint16_t count,
                             int timeout_ms = 500, int tries = 3);

// `size` bytes at `address`, read kGvcpReadMax at a time. Throws Error as gvcp_read_memory
// does, when the range does not fit the device's 32-bit addresses, or when the whole takes
// longer than `limit_s` (a device answering each read just in time would take hours).
std::string gvcp_read_range(const std::string& ipv4, uint64_t address, uint64_t size,
                            double limit_s = 60);

}  // namespace rangex
