#include "backends/registry.h"

#include "backends/backend_error.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/device_select.h"
#include "backends/fault_injection.h"
#include "core/error.h"
#if RANGEX_WITH_OPENCL
#include "backends/opencl/cl_runtime.h"
#include "backends/opencl/opencl_backend.h"
#endif
#if RANGEX_WITH_VULKAN
#include "backends/vulkan/vulkan_backend.h"
#endif

namespace rangex {

namespace {

// A device backend's probe: the devices `list` finds, or why there are none.
template <class F>
BackendProbe probe_devices(const char* name, F&& list, const char* none) {
  BackendProbe p;
  p.name = name;
  try {
    const auto devs = list();
    if (devs.empty()) {
      p.detail = none;
      return p;
    }
    p.available = true;
    p.detail = describe_devices(devs, p.emulated);
  } catch (const std::exception& e) {
    p.detail = e.what();
  }
  return p;
}

BackendProbe probe_opencl() {
#if RANGEX_WITH_OPENCL
  return probe_devices("opencl", cl::devices, "no OpenCL device with 64-bit floats");
#else
  return {"opencl", false, false, "not built (OpenCL headers or loader missing at build time)"};
#endif
}

BackendProbe probe_vulkan() {
#if RANGEX_WITH_VULKAN
  return probe_devices("vulkan", vulkan_devices,
                       "no Vulkan device with a compute queue and 64-bit floats");
#else
  return {"vulkan", false, false,
          "not built (Vulkan loader or glslangValidator missing at build time)"};
#endif
}

std::unique_ptr<Backend> start(const std::string& name, const BackendRequest& req) {
  if (name == "cpu") return std::make_unique<CpuBackend>(req.threads);
  if (name == "cpu-portable") return std::make_unique<CpuBackend>(req.threads, true);
#if RANGEX_WITH_OPENCL
  if (name == "opencl")
    return std::make_unique<OpenClBackend>(OpenClOptions{req.device, req.guards});
#endif
#if RANGEX_WITH_VULKAN
  if (name == "vulkan")
    return std::make_unique<VulkanBackend>(VulkanOptions{req.device, req.guards});
#endif
  for (const BackendProbe& p : probe_backends())
    if (p.name == name) throw BackendError(name + ": " + p.detail);
  throw BackendError("unknown backend '" + name + "' (auto, cpu, cpu-portable, opencl, vulkan)");
}

}  // namespace

std::vector<BackendProbe> probe_backends() {
  BackendProbe cpu{"cpu", true, false, std::string("host CPU, ") + stripe_vector_path()};
  BackendProbe portable{"cpu-portable", true, false, "host CPU, portable groups of 16 columns"};
  return {cpu, portable, probe_vulkan(), probe_opencl()};
}

static std::unique_ptr<Backend> with_faults(std::unique_ptr<Backend> b, const BackendRequest& req) {
  if (req.fail_after < 0 && req.corrupt_after < 0) return b;
  return std::make_unique<FaultInjectingBackend>(std::move(b),
                                                 FaultPlan{req.fail_after, req.corrupt_after});
}

std::unique_ptr<Backend> create_backend(const BackendRequest& req, std::string* why) {
  if (req.name != "auto") return with_faults(start(req.name, req), req);
  std::string note;
  for (const BackendProbe& p : probe_backends()) {
    if (p.name.rfind("cpu", 0) == 0) continue;
    if (!p.available) {
      note += p.name + ": " + p.detail + "; ";
      continue;
    }
    if (p.emulated) {
      note += p.name + ": only CPU emulations (" + p.detail + "), the CPU backend is faster; ";
      continue;
    }
    try {
      auto b = start(p.name, req);
      if (!b->info().emulated) {
        if (why) *why = "auto: " + p.name + " on a GPU";
        return with_faults(std::move(b), req);
      }
    } catch (const std::exception& e) {
      note += p.name + " could not start: " + e.what() + "; ";
    }
  }
  if (why) *why = "auto: cpu (" + note.substr(0, note.size() > 2 ? note.size() - 2 : 0) + ")";
  return with_faults(start("cpu", req), req);
}

}  // namespace rangex
