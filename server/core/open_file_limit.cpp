#include "core/open_file_limit.h"

#include <dirent.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rangex {

namespace {
uint64_t as_u64(rlim_t v) {
  return v == RLIM_INFINITY ? UINT64_MAX : uint64_t(v);
}
}  // namespace

OpenFileLimit raise_open_file_limit(uint64_t ceiling) {
  OpenFileLimit out;
  rlimit r{};
  if (getrlimit(RLIMIT_NOFILE, &r) != 0) {
    out.error = std::string("getrlimit(RLIMIT_NOFILE): ") + std::strerror(errno);
    return out;
  }
  out.before = out.now = as_u64(r.rlim_cur);
  out.hard = as_u64(r.rlim_max);
  const uint64_t want = std::min(out.hard, ceiling);
  if (out.before >= want) return out;
  r.rlim_cur = rlim_t(want);
  if (setrlimit(RLIMIT_NOFILE, &r) != 0) {
    out.error = std::string("setrlimit(RLIMIT_NOFILE): ") + std::strerror(errno);
    return out;
  }
  out.now = want;
  return out;
}

OpenFiles open_files() {
  OpenFiles out;
  rlimit r{};
  if (getrlimit(RLIMIT_NOFILE, &r) == 0) out.limit = as_u64(r.rlim_cur);
  DIR* d = opendir("/proc/self/fd");
  if (!d) return out;
  int64_t n = 0;
  while (const dirent* e = readdir(d))
    if (e->d_name[0] != '.') ++n;
  closedir(d);
  out.open = n - 1;  // less the listing's own
  return out;
}

}  // namespace rangex
