// What the OpenCL and Vulkan backends share about the devices they find: picking one by the
// plant's selector and describing them for the registry. D has `name` and `cpu` (a CPU
// emulation such as PoCL's device or lavapipe).
#pragma once
#include <cstdlib>
#include <string>
#include <vector>

#include "backends/backend_error.h"
#include "core/error.h"

namespace rangex {

// "" picks the first real GPU, else the first device; an index picks by position; anything
// else picks the first device whose name contains it. `api` names the backend in errors.
template <class D>
const D& select_device(const std::vector<D>& all, const std::string& selector, const char* api) {
  std::string names;
  for (size_t i = 0; i < all.size(); ++i)
    names += (i ? ", " : "") + std::to_string(i) + ": " + all[i].name;
  if (selector.empty()) {
    for (const auto& c : all)
      if (!c.cpu) return c;
    return all.front();
  }
  char* end = nullptr;
  const long idx = std::strtol(selector.c_str(), &end, 10);
  if (*end == '\0') {
    if (idx < 0 || idx >= long(all.size()))
      throw BackendError(join(api, ": no device ", selector, " (devices: ", names, ")"));
    return all[size_t(idx)];
  }
  for (const auto& c : all)
    if (c.name.find(selector) != std::string::npos) return c;
  throw BackendError(join(api, ": no device named like '", selector, "' (devices: ", names, ")"));
}

// "0: name (CPU); 1: name", and whether every device is a CPU emulation.
template <class D>
std::string describe_devices(const std::vector<D>& all, bool& all_emulated) {
  std::string out;
  all_emulated = !all.empty();
  for (size_t i = 0; i < all.size(); ++i) {
    all_emulated &= all[i].cpu;
    out += (i ? "; " : "") + std::to_string(i) + ": " + all[i].name + (all[i].cpu ? " (CPU)" : "");
  }
  return out;
}

}  // namespace rangex
