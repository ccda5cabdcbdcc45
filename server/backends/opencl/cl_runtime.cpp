#include "backends/opencl/cl_runtime.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "backends/device_select.h"
#include "backends/kernel_cache.h"
#include "core/error.h"

namespace fs = std::filesystem;

namespace rangex::cl {

const char* error_name(cl_int e) {
  switch (e) {
    case CL_SUCCESS:
      return "CL_SUCCESS";
    case CL_DEVICE_NOT_FOUND:
      return "CL_DEVICE_NOT_FOUND";
    case CL_DEVICE_NOT_AVAILABLE:
      return "CL_DEVICE_NOT_AVAILABLE";
    case CL_COMPILER_NOT_AVAILABLE:
      return "CL_COMPILER_NOT_AVAILABLE";
    case CL_MEM_OBJECT_ALLOCATION_FAILURE:
      return "CL_MEM_OBJECT_ALLOCATION_FAILURE";
    case CL_OUT_OF_RESOURCES:
      return "CL_OUT_OF_RESOURCES";
    case CL_OUT_OF_HOST_MEMORY:
      return "CL_OUT_OF_HOST_MEMORY";
    case CL_PROFILING_INFO_NOT_AVAILABLE:
      return "CL_PROFILING_INFO_NOT_AVAILABLE";
    case CL_BUILD_PROGRAM_FAILURE:
      return "CL_BUILD_PROGRAM_FAILURE";
    case CL_MISALIGNED_SUB_BUFFER_OFFSET:
      return "CL_MISALIGNED_SUB_BUFFER_OFFSET";
    case CL_INVALID_VALUE:
      return "CL_INVALID_VALUE";
    case CL_INVALID_PLATFORM:
      return "CL_INVALID_PLATFORM";
    case CL_INVALID_DEVICE:
      return "CL_INVALID_DEVICE";
    case CL_INVALID_CONTEXT:
      return "CL_INVALID_CONTEXT";
    case CL_INVALID_COMMAND_QUEUE:
      return "CL_INVALID_COMMAND_QUEUE";
    case CL_INVALID_MEM_OBJECT:
      return "CL_INVALID_MEM_OBJECT";
    case CL_INVALID_BINARY:
      return "CL_INVALID_BINARY";
    case CL_INVALID_BUILD_OPTIONS:
      return "CL_INVALID_BUILD_OPTIONS";
    case CL_INVALID_PROGRAM:
      return "CL_INVALID_PROGRAM";
    case CL_INVALID_PROGRAM_EXECUTABLE:
      return "CL_INVALID_PROGRAM_EXECUTABLE";
    case CL_INVALID_KERNEL_NAME:
      return "CL_INVALID_KERNEL_NAME";
    case CL_INVALID_KERNEL:
      return "CL_INVALID_KERNEL";
    case CL_INVALID_ARG_INDEX:
      return "CL_INVALID_ARG_INDEX";
    case CL_INVALID_ARG_VALUE:
      return "CL_INVALID_ARG_VALUE";
    case CL_INVALID_ARG_SIZE:
      return "CL_INVALID_ARG_SIZE";
    case CL_INVALID_KERNEL_ARGS:
      return "CL_INVALID_KERNEL_ARGS";
    case CL_INVALID_WORK_GROUP_SIZE:
      return "CL_INVALID_WORK_GROUP_SIZE";
    case CL_INVALID_GLOBAL_WORK_SIZE:
      return "CL_INVALID_GLOBAL_WORK_SIZE";
    case CL_INVALID_EVENT:
      return "CL_INVALID_EVENT";
    case CL_INVALID_BUFFER_SIZE:
      return "CL_INVALID_BUFFER_SIZE";
    case CL_PLATFORM_NOT_FOUND_KHR:
      return "CL_PLATFORM_NOT_FOUND_KHR (no OpenCL driver installed)";
    default:
      return "an OpenCL error";
  }
}

void check(cl_int e, const char* what) {
  if (e != CL_SUCCESS)
    throw BackendError(join("opencl: ", what, " failed: ", error_name(e), " (", e, ")"));
}

namespace {

std::string device_string(cl_device_id d, cl_device_info what) {
  size_t n = 0;
  check(clGetDeviceInfo(d, what, 0, nullptr, &n), "clGetDeviceInfo");
  std::string s(n, '\0');
  check(clGetDeviceInfo(d, what, n, s.data(), nullptr), "clGetDeviceInfo");
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
  return s;
}

template <typename T>
T device_value(cl_device_id d, cl_device_info what) {
  T v{};
  check(clGetDeviceInfo(d, what, sizeof v, &v, nullptr), "clGetDeviceInfo");
  return v;
}

std::string platform_string(cl_platform_id p, cl_platform_info what) {
  size_t n = 0;
  check(clGetPlatformInfo(p, what, 0, nullptr, &n), "clGetPlatformInfo");
  std::string s(n, '\0');
  check(clGetPlatformInfo(p, what, n, s.data(), nullptr), "clGetPlatformInfo");
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}

// FNV-1a, for file names of cache entries (the entry holds its full key).
uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

}  // namespace

std::vector<DeviceChoice> devices() {
  cl_uint np = 0;
  const cl_int e = clGetPlatformIDs(0, nullptr, &np);
  if (e == CL_PLATFORM_NOT_FOUND_KHR || np == 0) return {};
  check(e, "clGetPlatformIDs");
  std::vector<cl_platform_id> ps(np);
  check(clGetPlatformIDs(np, ps.data(), nullptr), "clGetPlatformIDs");
  std::vector<DeviceChoice> out;
  for (cl_platform_id p : ps) {
    cl_uint nd = 0;
    if (clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 0, nullptr, &nd) != CL_SUCCESS || nd == 0) continue;
    std::vector<cl_device_id> ds(nd);
    check(clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, nd, ds.data(), nullptr), "clGetDeviceIDs");
    for (cl_device_id d : ds) {
      DeviceChoice c;
      c.platform = p;
      c.device = d;
      c.name = device_string(d, CL_DEVICE_NAME);
      c.platform_name = platform_string(p, CL_PLATFORM_NAME);
      c.driver = device_string(d, CL_DRIVER_VERSION);
      c.version = device_string(d, CL_DEVICE_VERSION);
      c.cpu = (device_value<cl_device_type>(d, CL_DEVICE_TYPE) & CL_DEVICE_TYPE_CPU) != 0;
      c.global_mem = size_t(device_value<cl_ulong>(d, CL_DEVICE_GLOBAL_MEM_SIZE));
      c.max_alloc = size_t(device_value<cl_ulong>(d, CL_DEVICE_MAX_MEM_ALLOC_SIZE));
      c.max_work_group = device_value<size_t>(d, CL_DEVICE_MAX_WORK_GROUP_SIZE);
      c.compute_units = int(device_value<cl_uint>(d, CL_DEVICE_MAX_COMPUTE_UNITS));
      const std::string ext = device_string(d, CL_DEVICE_EXTENSIONS);
      if (ext.find("cl_khr_fp64") == std::string::npos) continue;  // the kernels need doubles
      out.push_back(c);
    }
  }
  return out;
}

DeviceChoice choose(const std::string& selector) {
  const auto all = devices();
  if (all.empty())
    throw BackendError(
        "opencl: no OpenCL device with 64-bit floats (no platform installed, or its devices "
        "lack cl_khr_fp64)");
  return select_device(all, selector, "opencl");
}

Buffer::Buffer(cl_context ctx, cl_mem_flags flags, size_t bytes, size_t guard, size_t align,
               cl_command_queue q)
    : bytes_(bytes) {
  cl_int e;
  if (guard == 0) {
    mem_ = clCreateBuffer(ctx, flags, std::max<size_t>(bytes, 4), nullptr, &e);
    check(e, "clCreateBuffer");
    return;
  }
  // The guard must keep the sub-buffer's origin aligned as the device requires.
  guard_ = (guard + align - 1) / align * align;
  mem_ = clCreateBuffer(ctx, flags & ~cl_mem_flags(CL_MEM_ALLOC_HOST_PTR), bytes + 2 * guard_,
                        nullptr, &e);
  check(e, "clCreateBuffer (guarded)");
  const uint8_t pattern = 0xA5;
  check(clEnqueueFillBuffer(q, mem_, &pattern, 1, 0, bytes + 2 * guard_, 0, nullptr, nullptr),
        "clEnqueueFillBuffer (guards)");
  cl_buffer_region region{guard_, std::max<size_t>(bytes, 4)};
  sub_ = clCreateSubBuffer(mem_, flags & (CL_MEM_READ_ONLY | CL_MEM_WRITE_ONLY | CL_MEM_READ_WRITE),
                           CL_BUFFER_CREATE_TYPE_REGION, &region, &e);
  check(e, "clCreateSubBuffer");
  check(clFinish(q), "clFinish (guards)");
}

Buffer::Buffer(cl_context ctx, cl_mem_flags flags, size_t bytes, const void* host) : bytes_(bytes) {
  cl_int e;
  mem_ = clCreateBuffer(ctx, flags | CL_MEM_USE_HOST_PTR, std::max<size_t>(bytes, 4),
                        const_cast<void*>(host), &e);
  check(e, "clCreateBuffer (host view)");
}

Buffer::Buffer(Buffer&& o) noexcept {
  *this = std::move(o);
}

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    release();
    mem_ = o.mem_;
    sub_ = o.sub_;
    bytes_ = o.bytes_;
    guard_ = o.guard_;
    o.mem_ = o.sub_ = nullptr;
  }
  return *this;
}

Buffer::~Buffer() {
  release();
}

void Buffer::release() {
  if (sub_) clReleaseMemObject(sub_);
  if (mem_) clReleaseMemObject(mem_);
  sub_ = mem_ = nullptr;
}

void Buffer::check_guards(cl_command_queue q, const char* what) const {
  if (!guard_) return;
  std::vector<uint8_t> g(guard_);
  for (size_t off : {size_t(0), guard_ + bytes_}) {
    check(clEnqueueReadBuffer(q, mem_, CL_TRUE, off, guard_, g.data(), 0, nullptr, nullptr),
          "clEnqueueReadBuffer (guards)");
    for (size_t i = 0; i < guard_; ++i)
      if (g[i] != 0xA5)
        throw BackendError(join("opencl: the kernel wrote outside buffer '", what, "' (",
                                off == 0 ? "before its start" : "past its end", ", byte ", i, ")"));
  }
}

Context::Context(const DeviceChoice& d) : dev_(d) {
  cl_int e;
  const cl_context_properties props[] = {CL_CONTEXT_PLATFORM, cl_context_properties(d.platform), 0};
  ctx_ = clCreateContext(props, 1, &d.device, nullptr, nullptr, &e);
  check(e, "clCreateContext");
  for (auto& q : queues_) {
    q = clCreateCommandQueue(ctx_, d.device, CL_QUEUE_PROFILING_ENABLE, &e);
    check(e, "clCreateCommandQueue");
  }
}

Context::~Context() {
  for (auto& q : queues_)
    if (q) clReleaseCommandQueue(q);
  if (ctx_) clReleaseContext(ctx_);
}

cl_program Context::program(const char* source, const char* hash, const std::string& options) {
  const std::string key = std::string(hash) + "|" + dev_.name + "|" + dev_.platform_name + "|" +
                          dev_.driver + "|" + dev_.version + "|" + options;
  const fs::path dir = kernel_cache_dir();
  char name[32];
  std::snprintf(name, sizeof name, "%016llx.clbin", (unsigned long long)fnv1a(key));
  const fs::path file = dir.empty() ? fs::path() : dir / name;
  cl_int e;
  // From the cache: the entry starts with its key, then the binary.
  if (!file.empty()) {
    std::ifstream in(file, std::ios::binary);
    std::string stored;
    if (in && std::getline(in, stored) && stored == key) {
      std::string bin((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      const unsigned char* ptr = reinterpret_cast<const unsigned char*>(bin.data());
      const size_t size = bin.size();
      cl_int status;
      cl_program p = clCreateProgramWithBinary(ctx_, 1, &dev_.device, &size, &ptr, &status, &e);
      if (e == CL_SUCCESS && status == CL_SUCCESS &&
          clBuildProgram(p, 1, &dev_.device, options.c_str(), nullptr, nullptr) == CL_SUCCESS) {
        cache_note_ = "program from cache " + file.string();
        return p;
      }
      if (p) clReleaseProgram(p);
    }
  }
  cl_program p = clCreateProgramWithSource(ctx_, 1, &source, nullptr, &e);
  check(e, "clCreateProgramWithSource");
  e = clBuildProgram(p, 1, &dev_.device, options.c_str(), nullptr, nullptr);
  if (e != CL_SUCCESS) {
    size_t n = 0;
    clGetProgramBuildInfo(p, dev_.device, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
    std::string log(n, '\0');
    clGetProgramBuildInfo(p, dev_.device, CL_PROGRAM_BUILD_LOG, n, log.data(), nullptr);
    clReleaseProgram(p);
    throw BackendError(join("opencl: building the kernels failed: ", error_name(e), "\n", log));
  }
  cache_note_ = "program compiled";
  if (!file.empty()) {
    size_t size = 0;
    if (clGetProgramInfo(p, CL_PROGRAM_BINARY_SIZES, sizeof size, &size, nullptr) == CL_SUCCESS &&
        size > 0) {
      std::string bin(size, '\0');
      unsigned char* ptr = reinterpret_cast<unsigned char*>(bin.data());
      if (clGetProgramInfo(p, CL_PROGRAM_BINARIES, sizeof ptr, &ptr, nullptr) == CL_SUCCESS) {
        std::error_code ec;
        fs::create_directories(dir, ec);
        const fs::path tmp = file.string() + ".tmp" + std::to_string(::getpid());
        std::ofstream out(tmp, std::ios::binary);
        out << key << '\n' << bin;
        out.close();
        if (out) fs::rename(tmp, file, ec);  // atomic: a reader sees all of it or nothing
        if (!ec) cache_note_ += ", cached in " + file.string();
      }
    }
  }
  return p;
}

double event_seconds(cl_event e) {
  cl_ulong a = 0, b = 0;
  if (clGetEventProfilingInfo(e, CL_PROFILING_COMMAND_START, sizeof a, &a, nullptr) != CL_SUCCESS ||
      clGetEventProfilingInfo(e, CL_PROFILING_COMMAND_END, sizeof b, &b, nullptr) != CL_SUCCESS)
    return 0;
  return double(b - a) * 1e-9;
}

void launch(cl_command_queue q, cl_kernel k, size_t n, std::vector<cl_event>& ev, size_t local) {
  if (n == 0) return;
  cl_event e;
  check(clEnqueueNDRangeKernel(q, k, 1, nullptr, &n, local ? &local : nullptr, 0, nullptr, &e),
        "clEnqueueNDRangeKernel");
  ev.push_back(e);
}

void write(cl_command_queue q, cl_mem m, const void* src, size_t bytes, std::vector<cl_event>& ev) {
  if (bytes == 0) return;
  cl_event e;
  check(clEnqueueWriteBuffer(q, m, CL_FALSE, 0, bytes, src, 0, nullptr, &e),
        "clEnqueueWriteBuffer");
  ev.push_back(e);
}

void read(cl_command_queue q, cl_mem m, void* dst, size_t bytes, std::vector<cl_event>& ev) {
  if (bytes == 0) return;
  cl_event e;
  check(clEnqueueReadBuffer(q, m, CL_FALSE, 0, bytes, dst, 0, nullptr, &e), "clEnqueueReadBuffer");
  ev.push_back(e);
}

double seconds(std::vector<cl_event>& ev) {
  double s = 0;
  for (cl_event e : ev) {
    s += event_seconds(e);
    clReleaseEvent(e);
  }
  ev.clear();
  return s;
}

}  // namespace rangex::cl
