// Which backends this build has and which can start on this machine, and the one to run.
// `auto` prefers a real GPU (Vulkan, then OpenCL) and stays on the CPU backend when the only
// devices are CPU emulations (lavapipe, PoCL): the native CPU path is faster there. Naming
// a backend always uses it, or says why it cannot start.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "backends/backend.h"

namespace rangex {

struct BackendProbe {
  std::string name;
  bool available = false;
  bool emulated = false;  // every device it found is a CPU emulation
  std::string detail;     // the devices found, or why it cannot start
};

std::vector<BackendProbe> probe_backends();

struct BackendRequest {
  std::string name = "auto";  // auto | cpu | opencl | vulkan
  std::string device;         // index or name substring (opencl, vulkan)
  int threads = 1;            // CPU stripe threads
  bool guards = false;        // guard bytes around device buffers (tests)
  int fail_after = -1;        // fault injection (tests): batches before every collect fails
  int corrupt_after = -1;     // fault injection (tests): batches before results go wrong
};

// The CPU reference backend with `threads` stripe workers.
inline BackendRequest cpu_request(int threads = 1) {
  BackendRequest r;
  r.name = "cpu";
  r.threads = threads;
  return r;
}

// Starts the requested backend. For `auto`, `why` says what was chosen and why; a named
// backend that cannot start throws BackendError with the reason.
std::unique_ptr<Backend> create_backend(const BackendRequest& req, std::string* why = nullptr);

}  // namespace rangex
