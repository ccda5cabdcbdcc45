// The process's limit on open files. Each client's connection is one, as are the store, the
// images being written, the devices' sockets and a recording's arrays: with the soft limit
// most services start with (1024), 1,100 idle connections to the gRPC port left rangexd
// unable to accept any client (a feeder, `rangexctl status`: "Too many open files"). rangexd
// raises the soft limit to the hard one at start, as Go's runtime and nginx do.
#pragma once
#include <cstdint>
#include <string>

namespace rangex {

struct OpenFileLimit {
  uint64_t before = 0, now = 0, hard = 0;  // RLIM_INFINITY as UINT64_MAX
  std::string error;                       // why it could not be raised ("" if it was, or was)
};

// Raises the soft limit to the hard one, at most `ceiling`.
OpenFileLimit raise_open_file_limit(uint64_t ceiling = uint64_t(1) << 20);

// Below this, a plant's clients can exhaust the process's files: rangexd warns.
constexpr uint64_t kFewOpenFiles = 4096;

// The files the process holds now and its soft limit. gRPC 1.51 bounds no count of
// connections: 19,600 idle ones to the gRPC port held 470 MB and, at the limit, locked every
// new gRPC client out while the dashboard still answered. This is what shows it.
struct OpenFiles {
  int64_t open = -1;   // -1: unknown (no /proc)
  uint64_t limit = 0;  // the soft limit (RLIM_INFINITY as UINT64_MAX); 0: unknown
};
OpenFiles open_files();

// Statistics warn from this share of the limit on: near it, accept() and open() fail.
constexpr double kOpenFilesWarnShare = 0.8;

}  // namespace rangex
