// A register's address or value as GigE Vision tools show it: 0x and eight hex digits.
#pragma once
#include <cstdint>
#include <cstdio>
#include <string>

namespace rangex {

inline std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08x", v);
  return b;
}

}  // namespace rangex
