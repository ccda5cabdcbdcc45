// OpenCL plumbing for the opencl backend: every call checked (BackendError names the call
// and the error), device selection, a context with two in-order queues (two batches in
// flight), buffers with optional guard bytes, and programs built from embedded source once
// per device and driver: compiled binaries are cached on disk, keyed on the source's hash,
// the device, the driver and the build options, so that a restart does not compile again.
#pragma once
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <CL/cl_ext.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "backends/backend_error.h"

namespace rangex::cl {

const char* error_name(cl_int e);
void check(cl_int e, const char* what);

struct DeviceChoice {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  std::string name, platform_name, driver, version;
  bool cpu = false;  // a CPU device (PoCL's pthread device): an emulation of a GPU
  size_t global_mem = 0, max_alloc = 0, max_work_group = 0;
  int compute_units = 0;
};

// Every device of every platform, in platform order.
std::vector<DeviceChoice> devices();
// selector: "" (the first GPU, else the first device), an index into devices(), or a
// substring of the device name. Throws BackendError saying what exists.
DeviceChoice choose(const std::string& selector);

// A buffer, optionally surrounded by guard bytes that the device must never write.
class Buffer {
 public:
  Buffer() = default;
  Buffer(cl_context ctx, cl_mem_flags flags, size_t bytes, size_t guard, size_t align,
         cl_command_queue q);
  // A view of host memory the device reads in place (CL_MEM_USE_HOST_PTR): on a CPU device
  // the kernels read the caller's bytes without a copy. No guards.
  Buffer(cl_context ctx, cl_mem_flags flags, size_t bytes, const void* host);
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  ~Buffer();
  cl_mem mem() const { return sub_ ? sub_ : mem_; }
  size_t bytes() const { return bytes_; }
  // Throws BackendError when a guard byte changed (a kernel wrote outside its buffer).
  void check_guards(cl_command_queue q, const char* what) const;

 private:
  void release();
  cl_mem mem_ = nullptr, sub_ = nullptr;
  size_t bytes_ = 0, guard_ = 0;
};

class Context {
 public:
  explicit Context(const DeviceChoice& d);
  ~Context();
  Context(const Context&) = delete;
  const DeviceChoice& device() const { return dev_; }
  cl_context ctx() const { return ctx_; }
  cl_command_queue queue(int i) const { return queues_[i]; }
  // The program of `source` (hash: its content hash), from the cache when it holds one.
  cl_program program(const char* source, const char* hash, const std::string& options);
  std::string cache_note() const { return cache_note_; }

 private:
  DeviceChoice dev_;
  cl_context ctx_ = nullptr;
  cl_command_queue queues_[2] = {nullptr, nullptr};
  std::string cache_note_;
};

// Seconds a profiled event spent between start and end.
double event_seconds(cl_event e);

// Enqueueing, every call checked: each call that enqueues work appends its event to `ev`.
// Kernel arguments in order: buffers as cl_mem, numbers by value.
template <typename T>
void arg(cl_kernel k, cl_uint i, const T& v) {
  check(clSetKernelArg(k, i, sizeof v, &v), "clSetKernelArg");
}
template <typename... A>
void args(cl_kernel k, const A&... a) {
  cl_uint i = 0;
  (arg(k, i++, a), ...);
}
// n work-items in groups of `local` (0: the driver's choice); nothing for n = 0.
void launch(cl_command_queue q, cl_kernel k, size_t n, std::vector<cl_event>& ev, size_t local = 0);
// Non-blocking copies host -> device and device -> host; nothing for 0 bytes.
void write(cl_command_queue q, cl_mem m, const void* src, size_t bytes, std::vector<cl_event>& ev);
void read(cl_command_queue q, cl_mem m, void* dst, size_t bytes, std::vector<cl_event>& ev);
// The seconds the events of `ev` spent, summed; they are released and `ev` left empty.
double seconds(std::vector<cl_event>& ev);

}  // namespace rangex::cl
