#include "backends/opencl/opencl_backend.h"

#include <algorithm>
#include <string>

#include "backends/opencl/opencl_backend_impl.h"
#include "core/error.h"
#include "kernels_cl.h"

namespace rangex {

OpenClBackend::OpenClBackend(const OpenClOptions& opt) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.opt = opt;
  const cl::DeviceChoice d = cl::choose(opt.device);
  m.cx = std::make_unique<cl::Context>(d);
  cl_uint bits = 1024;
  clGetDeviceInfo(d.device, CL_DEVICE_MEM_BASE_ADDR_ALIGN, sizeof bits, &bits, nullptr);
  m.align = std::max<size_t>(bits / 8, 4);
  m.program = m.cx->program(kernels::kLineKernels, kernels::kLineKernelsHash, "-cl-std=CL1.2");
  cl_int e;
  auto kernel = [&](const char* name) {
    cl_kernel k = clCreateKernel(m.program, name, &e);
    cl::check(e, (std::string("clCreateKernel ") + name).c_str());
    return k;
  };
  m.k_stripe = kernel("stripe");
  m.k_stripe16 = kernel("stripe16");
  m.cpu_device = d.cpu;
  m.k_rectify = kernel("rectify");
  m.k_resample = kernel("fuse_resample");
  m.k_merge = kernel("fuse_merge");
  m.k_project = kernel("project");
  m.k_pseudo = kernel("pseudo_xray");
  m.k_irls = kernel("irls_sums");
  m.k_dual = kernel("dual_energy");
  m.k_bone = kernel("dual_energy_bone");
  info_.name = "opencl";
  info_.device = d.name + " (" + d.platform_name + ")";
  info_.driver = d.version + ", driver " + d.driver;
  info_.emulated = d.cpu;
  info_.overlaps = true;
  info_.limits = std::to_string(d.compute_units) + " compute units, " +
                 std::to_string(d.global_mem >> 20) + " MiB, max allocation " +
                 std::to_string(d.max_alloc >> 20) + " MiB, work-groups of " +
                 std::to_string(d.max_work_group) + "; " + m.cx->cache_note();
  for (int i = 0; i < 2; ++i) m.slots[i].queue = i;
}

OpenClBackend::~OpenClBackend() {
  Impl& m = *impl_;
  for (int i = 0; i < 2; ++i)
    if (m.cx) clFinish(m.q(i));
  for (cl_kernel k : {m.k_stripe, m.k_stripe16, m.k_rectify, m.k_resample, m.k_merge, m.k_project,
                      m.k_pseudo, m.k_irls, m.k_dual, m.k_bone})
    if (k) clReleaseKernel(k);
  if (m.program) clReleaseProgram(m.program);
  for (auto& s : m.slots)
    for (auto* v : {&s.up, &s.run, &s.down}) cl::seconds(*v);
}

void OpenClBackend::set_lanes(const std::vector<LaneConfig>& lanes) {
  for (const auto& s : impl_->slots)
    if (s.busy) fail("backend opencl: lanes changed with a batch in flight");
  impl_->tables.set_lanes(lanes);
  impl_->upload_tables();
  lanes_ = lanes;
  for (auto& s : impl_->slots) s.dev = {};  // sizes may have changed
  impl_->scratch = {};
}

void OpenClBackend::update_lane(int slot, const LaneConfig& lane) {
  for (const auto& s : impl_->slots)
    if (s.busy) fail("backend opencl: a lane changed with a batch in flight");
  impl_->tables.update_lane(slot, lane);
  impl_->upload_tables();
  lanes_.at(slot) = lane;
}

LineBatchSlot& OpenClBackend::acquire(int lines) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend opencl: no lanes set");
  // The free slot (batches may be collected in any order).
  if (m.slots[m.next].busy) m.next = 1 - m.next;
  Impl::Slot& s = m.slots[m.next];
  if (s.busy) fail("backend opencl: both staging slots are in flight; collect one first");
  m.next = 1 - m.next;
  if (lines > s.capacity()) {
    // Pinned staging, mapped once for the slot's life: the engine writes frames straight
    // into memory the device copies from.
    const size_t frame = size_t(m.tables.width) * m.tables.height;
    const size_t bytes = size_t(lines) * 2 * frame;
    s.pinned = cl::Buffer(m.cx->ctx(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, bytes, 0, m.align,
                          m.q(s.queue));
    cl_int e;
    void* p = clEnqueueMapBuffer(m.q(s.queue), s.pinned.mem(), CL_TRUE, CL_MAP_WRITE, 0, bytes, 0,
                                 nullptr, nullptr, &e);
    cl::check(e, "clEnqueueMapBuffer (staging)");
    s.lanes_host.resize(size_t(lines));
    s.set(static_cast<uint8_t*>(p), s.lanes_host.data(), lines);
  }
  m.ensure(s.dev, lines);
  s.lines = lines;
  s.busy = true;
  s.submitted = false;
  return s;
}

void OpenClBackend::submit(LineBatchSlot& batch) {
  Impl& m = *impl_;
  auto& s = static_cast<Impl::Slot&>(batch);
  const cl_command_queue qq = m.q(s.queue);
  const int lines = s.lines, count = lines * 2;
  const size_t W = size_t(m.tables.width);
  s.frame_slot_host.resize(size_t(count));
  for (int l = 0; l < lines; ++l) {
    if (s.lane_slot()[l] < 0 || s.lane_slot()[l] >= int(lanes_.size()))
      fail("line ", l, " of the batch names lane slot ", s.lane_slot()[l], " which does not exist");
    s.frame_slot_host[2 * l] = s.lane_slot()[l] * 2;
    s.frame_slot_host[2 * l + 1] = s.lane_slot()[l] * 2 + 1;
  }
  const cl_mem frames =
      m.frames_in(qq, s.dev, s.frames(), size_t(count) * W * m.tables.height, s.view, s.up);
  cl::write(qq, s.dev.frame_slot.mem(), s.frame_slot_host.data(), size_t(count) * 4, s.up);
  cl::write(qq, s.dev.lane_slot.mem(), s.lane_slot(), size_t(lines) * 4, s.up);
  m.enqueue_stripes(qq, s.dev, frames, count, s.run);
  m.enqueue_rectify(qq, s.dev, count, s.run);
  m.enqueue_fuse(qq, s.dev, lines, s.run);
  m.enqueue_project(qq, s.dev, lines, s.run);
  cl::check(clFlush(qq), "clFlush");
  s.submitted = true;
}

void OpenClBackend::collect(LineBatchSlot& batch, LineResults& out) {
  Impl& m = *impl_;
  auto& s = static_cast<Impl::Slot&>(batch);
  if (!s.submitted) submit(batch);
  const cl_command_queue qq = m.q(s.queue);
  const LineExtents e = LineExtents::of(m.tables, s.lines);
  const auto to = s.readback.prepare(e, out);
  s.dev.outputs(e, [&](cl::Buffer& b, size_t bytes, size_t k) {
    cl::read(qq, b.mem(), to[k], bytes, s.down);
  });
  m.finish(qq);
  m.check_guards(s.dev, qq);
  s.readback.finish(out);
  times_ = {cl::seconds(s.up), cl::seconds(s.run), cl::seconds(s.down)};
  s.busy = s.submitted = false;
}

}  // namespace rangex
