#include "backends/vulkan/vk_runtime.h"

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "backends/device_select.h"
#include "backends/kernel_cache.h"
#include "core/error.h"

namespace fs = std::filesystem;

namespace rangex::vk {

const char* result_name(VkResult r) {
  switch (r) {
    case VK_SUCCESS:
      return "VK_SUCCESS";
    case VK_NOT_READY:
      return "VK_NOT_READY";
    case VK_TIMEOUT:
      return "VK_TIMEOUT";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST:
      return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED:
      return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT:
      return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
      return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT:
      return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "VK_ERROR_INCOMPATIBLE_DRIVER (no Vulkan driver installed)";
    case VK_ERROR_TOO_MANY_OBJECTS:
      return "VK_ERROR_TOO_MANY_OBJECTS";
    case VK_ERROR_FORMAT_NOT_SUPPORTED:
      return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    case VK_ERROR_FRAGMENTED_POOL:
      return "VK_ERROR_FRAGMENTED_POOL";
    case VK_ERROR_OUT_OF_POOL_MEMORY:
      return "VK_ERROR_OUT_OF_POOL_MEMORY";
    default:
      return "a Vulkan error";
  }
}

void check(VkResult r, const char* what) {
  if (r != VK_SUCCESS)
    throw BackendError(join("vulkan: ", what, " failed: ", result_name(r), " (", int(r), ")"));
}

Instance::Instance() {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "rangex";
  app.apiVersion = VK_API_VERSION_1_1;
  VkInstanceCreateInfo ci{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ci.pApplicationInfo = &app;
  check(vkCreateInstance(&ci, nullptr, &inst_), "vkCreateInstance");
}

Instance::~Instance() {
  if (inst_) vkDestroyInstance(inst_, nullptr);
}

std::vector<DeviceChoice> Instance::devices() const {
  uint32_t n = 0;
  check(vkEnumeratePhysicalDevices(inst_, &n, nullptr), "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> pds(n);
  check(vkEnumeratePhysicalDevices(inst_, &n, pds.data()), "vkEnumeratePhysicalDevices");
  std::vector<DeviceChoice> out;
  for (VkPhysicalDevice pd : pds) {
    DeviceChoice c;
    c.physical = pd;
    vkGetPhysicalDeviceProperties(pd, &c.props);
    VkPhysicalDeviceFeatures f;
    vkGetPhysicalDeviceFeatures(pd, &f);
    if (!f.shaderFloat64) continue;  // fusion and projection compute in double
    uint32_t nq = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &nq, nullptr);
    std::vector<VkQueueFamilyProperties> qs(nq);
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &nq, qs.data());
    bool found = false;
    for (uint32_t i = 0; i < nq && !found; ++i)
      if (qs[i].queueFlags & VK_QUEUE_COMPUTE_BIT) {
        c.queue_family = i;
        found = true;
      }
    if (!found) continue;
    c.name = c.props.deviceName;
    c.cpu = c.props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
    out.push_back(c);
  }
  return out;
}

DeviceChoice Instance::choose(const std::string& selector) const {
  const auto all = devices();
  if (all.empty()) throw BackendError("vulkan: no device with a compute queue and 64-bit floats");
  return select_device(all, selector, "vulkan");
}

Device::Device(const Instance&, const DeviceChoice& d) : choice_(d), family_(d.queue_family) {
  const float prio = 1.0f;
  VkDeviceQueueCreateInfo q{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  q.queueFamilyIndex = family_;
  q.queueCount = 1;
  q.pQueuePriorities = &prio;
  VkPhysicalDeviceFeatures feats{};
  feats.shaderFloat64 = VK_TRUE;
  VkDeviceCreateInfo ci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  ci.queueCreateInfoCount = 1;
  ci.pQueueCreateInfos = &q;
  ci.pEnabledFeatures = &feats;
  check(vkCreateDevice(d.physical, &ci, nullptr, &dev_), "vkCreateDevice");
  vkGetDeviceQueue(dev_, family_, 0, &queue_);
  vkGetPhysicalDeviceMemoryProperties(d.physical, &mem_);
  // Unified when the device shares the host's memory (an integrated GPU, a CPU emulation)
  // and some memory type is both device-local and host-visible. A discrete GPU whose whole
  // memory the host can map (resizable BAR) is not: host reads across the bus crawl, so its
  // results come back through copies into cached host memory.
  const bool shares_host = d.props.deviceType == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU ||
                           d.props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  for (uint32_t i = 0; shares_host && i < mem_.memoryTypeCount; ++i) {
    const auto f = mem_.memoryTypes[i].propertyFlags;
    const auto heap = mem_.memoryHeaps[mem_.memoryTypes[i].heapIndex].size;
    if ((f & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) && (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) &&
        (f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) && heap > (VkDeviceSize(1) << 30))
      unified_ = true;
  }
  // The pipeline cache, from disk when this device and driver wrote one.
  std::vector<char> initial;
  const fs::path dir = kernel_cache_dir();
  if (!dir.empty()) {
    char name[96];
    std::snprintf(name, sizeof name, "vk-%04x-%04x-%08x.bin", d.props.vendorID, d.props.deviceID,
                  d.props.driverVersion);
    cache_file_ = (dir / name).string();
    std::ifstream in(cache_file_, std::ios::binary);
    if (in) initial.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  VkPipelineCacheCreateInfo pc{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  pc.initialDataSize = initial.size();  // the driver checks the header and ignores a stale one
  pc.pInitialData = initial.empty() ? nullptr : initial.data();
  check(vkCreatePipelineCache(dev_, &pc, nullptr, &cache_), "vkCreatePipelineCache");
  cache_note_ = initial.empty() ? "pipelines compiled" : "pipelines from cache " + cache_file_;
}

Device::~Device() {
  if (dev_) {
    vkDeviceWaitIdle(dev_);
    if (cache_) vkDestroyPipelineCache(dev_, cache_, nullptr);
    vkDestroyDevice(dev_, nullptr);
  }
}

void Device::save_cache() const {
  if (cache_file_.empty()) return;
  size_t n = 0;
  if (vkGetPipelineCacheData(dev_, cache_, &n, nullptr) != VK_SUCCESS || n == 0) return;
  std::vector<char> data(n);
  if (vkGetPipelineCacheData(dev_, cache_, &n, data.data()) != VK_SUCCESS) return;
  std::error_code ec;
  fs::create_directories(fs::path(cache_file_).parent_path(), ec);
  const std::string tmp = cache_file_ + ".tmp" + std::to_string(::getpid());
  std::ofstream out(tmp, std::ios::binary);
  out.write(data.data(), std::streamsize(n));
  out.close();
  if (out) fs::rename(tmp, cache_file_, ec);  // atomic: a reader sees all of it or nothing
}

uint32_t Device::memory_type(uint32_t bits, VkMemoryPropertyFlags need,
                             VkMemoryPropertyFlags want) {
  int best = -1;
  for (uint32_t i = 0; i < mem_.memoryTypeCount; ++i) {
    const auto f = mem_.memoryTypes[i].propertyFlags;
    if (!(bits & (1u << i)) || (f & need) != need) continue;
    if ((f & want) == want) return i;
    if (best < 0) best = int(i);
  }
  if (best < 0) throw BackendError("vulkan: no memory type fits a buffer");
  return uint32_t(best);
}

Buffer Device::buffer(VkDeviceSize bytes, bool host, VkDeviceSize guard) {
  Buffer b;
  const VkDeviceSize align =
      std::max<VkDeviceSize>(choice_.props.limits.minStorageBufferOffsetAlignment, 16);
  b.guard = guard ? (guard + align - 1) / align * align : 0;
  b.offset = b.guard;
  b.bytes = std::max<VkDeviceSize>((bytes + 3) / 4 * 4, 4);
  const bool mapped = host || guard || unified_;
  VkBufferCreateInfo ci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  ci.size = b.bytes + 2 * b.guard;
  ci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
             VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  ci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkCreateBuffer(dev_, &ci, nullptr, &b.buf), "vkCreateBuffer");
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(dev_, b.buf, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex =
      mapped
          ? memory_type(
                req.memoryTypeBits,
                VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
                unified_ ? VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT : VK_MEMORY_PROPERTY_HOST_CACHED_BIT)
          : memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
  const VkResult r = vkAllocateMemory(dev_, &ai, nullptr, &b.mem);
  if (r != VK_SUCCESS) {
    vkDestroyBuffer(dev_, b.buf, nullptr);
    check(r, "vkAllocateMemory");
  }
  check(vkBindBufferMemory(dev_, b.buf, b.mem, 0), "vkBindBufferMemory");
  if (mapped) {
    void* p = nullptr;
    check(vkMapMemory(dev_, b.mem, 0, VK_WHOLE_SIZE, 0, &p), "vkMapMemory");
    b.map = static_cast<uint8_t*>(p);
    if (b.guard) {
      std::memset(b.map, 0xA5, size_t(b.guard));
      std::memset(b.map + b.guard + b.bytes, 0xA5, size_t(b.guard));
    }
  }
  return b;
}

void Device::destroy(Buffer& b) {
  if (b.map) vkUnmapMemory(dev_, b.mem);
  if (b.buf) vkDestroyBuffer(dev_, b.buf, nullptr);
  if (b.mem) vkFreeMemory(dev_, b.mem, nullptr);
  b = Buffer{};
}

void Device::check_guards(const Buffer& b, const char* what) const {
  if (!b.guard) return;
  for (VkDeviceSize i = 0; i < b.guard; ++i) {
    if (b.map[i] != 0xA5)
      throw BackendError(
          join("vulkan: a shader wrote before the start of buffer '", what, "' (byte ", i, ")"));
    if (b.map[b.guard + b.bytes + i] != 0xA5)
      throw BackendError(
          join("vulkan: a shader wrote past the end of buffer '", what, "' (byte ", i, ")"));
  }
}

Kernel make_kernel(Device& d, const uint32_t* spirv, size_t bytes, int bindings,
                   uint32_t push_bytes) {
  Kernel k;
  k.bindings = bindings;
  k.push_bytes = push_bytes;
  VkShaderModuleCreateInfo sm{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  sm.codeSize = bytes;
  sm.pCode = spirv;
  VkShaderModule module;
  check(vkCreateShaderModule(d.get(), &sm, nullptr, &module), "vkCreateShaderModule");
  std::vector<VkDescriptorSetLayoutBinding> bs(static_cast<size_t>(bindings));
  for (int i = 0; i < bindings; ++i) {
    bs[i].binding = uint32_t(i);
    bs[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    bs[i].descriptorCount = 1;
    bs[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  }
  VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  dl.bindingCount = uint32_t(bindings);
  dl.pBindings = bs.data();
  check(vkCreateDescriptorSetLayout(d.get(), &dl, nullptr, &k.set_layout),
        "vkCreateDescriptorSetLayout");
  VkPushConstantRange pr{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
  VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pl.setLayoutCount = 1;
  pl.pSetLayouts = &k.set_layout;
  pl.pushConstantRangeCount = 1;
  pl.pPushConstantRanges = &pr;
  check(vkCreatePipelineLayout(d.get(), &pl, nullptr, &k.layout), "vkCreatePipelineLayout");
  VkComputePipelineCreateInfo cp{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  cp.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
  cp.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cp.stage.module = module;
  cp.stage.pName = "main";
  cp.layout = k.layout;
  const VkResult r = vkCreateComputePipelines(d.get(), d.cache(), 1, &cp, nullptr, &k.pipeline);
  vkDestroyShaderModule(d.get(), module, nullptr);
  check(r, "vkCreateComputePipelines");
  return k;
}

void destroy(Device& d, Kernel& k) {
  if (k.pipeline) vkDestroyPipeline(d.get(), k.pipeline, nullptr);
  if (k.layout) vkDestroyPipelineLayout(d.get(), k.layout, nullptr);
  if (k.set_layout) vkDestroyDescriptorSetLayout(d.get(), k.set_layout, nullptr);
  k = Kernel{};
}

}  // namespace rangex::vk
