// Vulkan plumbing for the vulkan backend: every call checked (BackendError names the call
// and the result), device selection, a device with one compute queue and 64-bit floats,
// buffers (host-visible where the device allows, optionally with guard bytes), and compute
// pipelines from embedded SPIR-V through a pipeline cache kept on disk per device and
// driver, so that a restart does not compile the shaders again.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

#include "backends/backend_error.h"

namespace rangex::vk {

const char* result_name(VkResult r);
void check(VkResult r, const char* what);

struct DeviceChoice {
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties props{};
  uint32_t queue_family = 0;
  std::string name;
  bool cpu = false;  // a CPU implementation (lavapipe): an emulation of a GPU
};

class Instance {
 public:
  Instance();
  ~Instance();
  Instance(const Instance&) = delete;
  VkInstance get() const { return inst_; }
  // Devices with a compute queue and 64-bit floats, in enumeration order.
  std::vector<DeviceChoice> devices() const;
  // selector: "" (the first GPU, else the first device), an index, or a name substring.
  DeviceChoice choose(const std::string& selector) const;

 private:
  VkInstance inst_ = VK_NULL_HANDLE;
};

struct Buffer {
  VkBuffer buf = VK_NULL_HANDLE;
  VkDeviceMemory mem = VK_NULL_HANDLE;
  VkDeviceSize bytes = 0;   // usable bytes
  VkDeviceSize offset = 0;  // where they start (after the leading guard)
  VkDeviceSize guard = 0;
  uint8_t* map = nullptr;  // host-visible buffers stay mapped; data at map + offset
  uint8_t* data() const { return map ? map + offset : nullptr; }
};

class Device {
 public:
  Device(const Instance& inst, const DeviceChoice& d);
  ~Device();
  Device(const Device&) = delete;
  VkDevice get() const { return dev_; }
  VkQueue queue() const { return queue_; }
  uint32_t family() const { return family_; }
  const DeviceChoice& choice() const { return choice_; }
  // Device-local memory the host can map (integrated GPUs, lavapipe): no copies needed.
  bool unified() const { return unified_; }

  // host: mapped (staging, readback, or everything on a unified device); guard: bytes
  // before and after that the device must never write (host-visible, checked on the host).
  Buffer buffer(VkDeviceSize bytes, bool host, VkDeviceSize guard = 0);
  void destroy(Buffer& b);
  void check_guards(const Buffer& b, const char* what) const;

  VkPipelineCache cache() const { return cache_; }
  void save_cache() const;
  std::string cache_note() const { return cache_note_; }

 private:
  uint32_t memory_type(uint32_t bits, VkMemoryPropertyFlags need, VkMemoryPropertyFlags want);
  DeviceChoice choice_;
  VkDevice dev_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t family_ = 0;
  VkPhysicalDeviceMemoryProperties mem_{};
  bool unified_ = false;
  VkPipelineCache cache_ = VK_NULL_HANDLE;
  std::string cache_file_, cache_note_;
};

// A compute pipeline: `bindings` storage buffers in set 0, a push-constant block.
struct Kernel {
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  int bindings = 0;
  uint32_t push_bytes = 0;
};
Kernel make_kernel(Device& d, const uint32_t* spirv, size_t bytes, int bindings,
                   uint32_t push_bytes);
void destroy(Device& d, Kernel& k);

}  // namespace rangex::vk
