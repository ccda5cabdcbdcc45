// --backend, --device and --threads as rangexctl's commands read them.
#pragma once
#include <string>
#include <vector>

#include "args.h"
#include "backends/registry.h"

namespace rangex::cli {

// The backend a command runs on: --backend (default `def`), --device, --threads.
BackendRequest backend_request(const Args& a, const std::string& def);

// The backends named by a --backend value: one name, or `all`: every backend that can start
// here, the CPU first (the one the others are measured against).
std::vector<std::string> backend_names(const std::string& value);

}  // namespace rangex::cli
