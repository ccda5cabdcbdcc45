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

}  // namespace rangex
