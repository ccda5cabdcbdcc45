#include "core/size_limits.h"

#include <cstdio>

#include "core/error.h"

namespace rangex {

namespace {
std::string human(size_t bytes) {
  char b[64];
  if (bytes >= (size_t(1) << 20))
    std::snprintf(b, sizeof b, "%.1f MiB", double(bytes) / double(size_t(1) << 20));
  else
    std::snprintf(b, sizeof b, "%zu bytes", bytes);
  return b;
}
}  // namespace

void check_size(const std::string& what, size_t bytes, size_t limit) {
  if (bytes > limit)
    fail(what, " is ", human(bytes), ", more than the ", human(limit),
         " allowed; refused before parsing");
}

void check_name(const std::string& what, const std::string& name, size_t max_bytes) {
  if (name.empty()) fail(what, " is empty");
  if (name.size() > max_bytes)
    fail(what, " is ", human(name.size()), ", more than the ", max_bytes, " allowed");
  for (size_t i = 0; i < name.size(); ++i)
    if (const unsigned char c = static_cast<unsigned char>(name[i]); c < 0x20 || c == 0x7F) {
      char code[8];
      std::snprintf(code, sizeof code, "0x%02X", unsigned(c));
      fail(what, " '", name.substr(0, i), "...' holds the control character ", code, " at ", i);
    }
}

}  // namespace rangex
