#include "core/heap_trim.h"

#include <malloc.h>
#include <unistd.h>

#include <cstdio>

namespace rangex {

namespace {
// Resident bytes of this process (0 where /proc cannot be read).
size_t resident_bytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long size = 0, resident = 0;
  const int n = std::fscanf(f, "%lu %lu", &size, &resident);
  std::fclose(f);
  return n == 2 ? size_t(resident) * size_t(sysconf(_SC_PAGESIZE)) : 0;
}
}  // namespace

size_t return_free_heap() {
  const size_t before = resident_bytes();
  malloc_trim(0);
  const size_t after = resident_bytes();
  return before > after ? before - after : 0;
}

}  // namespace rangex
