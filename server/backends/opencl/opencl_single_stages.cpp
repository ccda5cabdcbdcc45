// The opencl backend's single stages (the stage tests and benchmarks): inputs uploaded, one
// stage run, outputs read back, on queue 0.
#include <algorithm>
#include <cstring>
#include <vector>

#include "backends/opencl/opencl_backend.h"
#include "backends/opencl/opencl_backend_impl.h"
#include "core/error.h"

namespace rangex {

namespace {

// The kernels' flags are 32-bit; the host's are bytes.
void to_flags(const std::vector<int32_t>& in, size_t n, uint8_t* out) {
  for (size_t i = 0; i < n; ++i) out[i] = uint8_t(in[i] != 0);
}
std::vector<int32_t> from_flags(const uint8_t* in, size_t n) {
  std::vector<int32_t> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = in[i];
  return v;
}

}  // namespace

void OpenClBackend::stripes(const uint8_t* frames, int count, const int* frame_slot,
                            StripeOutput& out) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend opencl: no lanes set");
  const cl_command_queue qq = m.q(0);
  m.ensure(m.scratch, (count + 1) / 2);
  const size_t cols = size_t(count) * m.tables.width;
  std::vector<cl_event> up, run, down;
  cl::Buffer view;
  const cl_mem in = m.frames_in(qq, m.scratch, frames, cols * m.tables.height, view, up);
  cl::write(qq, m.scratch.frame_slot.mem(), frame_slot, size_t(count) * 4, up);
  m.enqueue_stripes(qq, m.scratch, in, count, run);
  out.resize(cols);
  std::vector<int32_t> valid(cols);
  cl::read(qq, m.scratch.row.mem(), out.row.data(), cols * 4, down);
  cl::read(qq, m.scratch.peak.mem(), out.peak.data(), cols * 4, down);
  cl::read(qq, m.scratch.width.mem(), out.width.data(), cols * 4, down);
  cl::read(qq, m.scratch.asym.mem(), out.asym.data(), cols * 4, down);
  cl::read(qq, m.scratch.centroid.mem(), out.centroid.data(), cols * 4, down);
  cl::read(qq, m.scratch.valid.mem(), valid.data(), cols * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(valid, cols, out.valid.data());
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

void OpenClBackend::rectify(const float* row, const uint8_t* valid, int count,
                            const int* frame_slot, float* x, float* z, uint8_t* out_valid) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend opencl: no lanes set");
  const cl_command_queue qq = m.q(0);
  m.ensure(m.scratch, (count + 1) / 2);
  const size_t cols = size_t(count) * m.tables.width;
  const std::vector<int32_t> vin = from_flags(valid, cols);
  std::vector<int32_t> vout(cols);
  std::vector<cl_event> up, run, down;
  cl::write(qq, m.scratch.row.mem(), row, cols * 4, up);
  cl::write(qq, m.scratch.valid.mem(), vin.data(), cols * 4, up);
  cl::write(qq, m.scratch.frame_slot.mem(), frame_slot, size_t(count) * 4, up);
  m.enqueue_rectify(qq, m.scratch, count, run);
  cl::read(qq, m.scratch.x.mem(), x, cols * 4, down);
  cl::read(qq, m.scratch.z.mem(), z, cols * 4, down);
  cl::read(qq, m.scratch.xz_valid.mem(), vout.data(), cols * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, cols, out_valid);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

void OpenClBackend::fuse(const float* x, const float* z, const uint8_t* valid, int lines,
                         const int* lane_slot, float* profile, uint8_t* profile_valid,
                         FusionStats* stats) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend opencl: no lanes set");
  const cl_command_queue qq = m.q(0);
  m.ensure(m.scratch, lines);
  const size_t cols = size_t(lines) * 2 * m.tables.width, G = size_t(m.tables.grid_n);
  const std::vector<int32_t> vin = from_flags(valid, cols);
  std::vector<int32_t> vout(size_t(lines) * G);
  std::vector<kernel::FusionCountK> counts(static_cast<size_t>(lines));
  std::vector<cl_event> up, run, down;
  cl::write(qq, m.scratch.x.mem(), x, cols * 4, up);
  cl::write(qq, m.scratch.z.mem(), z, cols * 4, up);
  cl::write(qq, m.scratch.xz_valid.mem(), vin.data(), cols * 4, up);
  cl::write(qq, m.scratch.lane_slot.mem(), lane_slot, size_t(lines) * 4, up);
  m.enqueue_fuse(qq, m.scratch, lines, run);
  cl::read(qq, m.scratch.profile.mem(), profile, size_t(lines) * G * 4, down);
  cl::read(qq, m.scratch.profile_valid.mem(), vout.data(), size_t(lines) * G * 4, down);
  cl::read(qq, m.scratch.counts.mem(), counts.data(), size_t(lines) * sizeof(kernel::FusionCountK),
           down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, size_t(lines) * G, profile_valid);
  if (stats) add_fusion_counts(counts.data(), counts.size(), *stats);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

void OpenClBackend::project(const float* profile, const uint8_t* profile_valid, int lines,
                            const int* lane_slot, float* thickness, uint8_t* thickness_valid) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend opencl: no lanes set");
  const cl_command_queue qq = m.q(0);
  m.ensure(m.scratch, lines);
  const size_t G = size_t(m.tables.grid_n), P = size_t(m.tables.pixels);
  const std::vector<int32_t> vin = from_flags(profile_valid, size_t(lines) * G);
  // The highest valid sample of each line, as the fusion kernel leaves it for the projection.
  std::vector<float> top(size_t(lines), 0.f);
  for (int l = 0; l < lines; ++l)
    for (size_t g = 0; g < G; ++g)
      if (profile_valid[size_t(l) * G + g]) top[l] = std::max(top[l], profile[size_t(l) * G + g]);
  std::vector<int32_t> vout(size_t(lines) * P);
  std::vector<cl_event> up, run, down;
  cl::write(qq, m.scratch.profile.mem(), profile, size_t(lines) * G * 4, up);
  cl::write(qq, m.scratch.profile_valid.mem(), vin.data(), size_t(lines) * G * 4, up);
  cl::write(qq, m.scratch.top.mem(), top.data(), size_t(lines) * 4, up);
  cl::write(qq, m.scratch.lane_slot.mem(), lane_slot, size_t(lines) * 4, up);
  m.enqueue_project(qq, m.scratch, lines, run);
  cl::read(qq, m.scratch.thickness.mem(), thickness, size_t(lines) * P * 4, down);
  cl::read(qq, m.scratch.thickness_valid.mem(), vout.data(), size_t(lines) * P * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, size_t(lines) * P, thickness_valid);
  times_ = {cl::seconds(up), cl::seconds(run), cl::seconds(down)};
}

double OpenClBackend::upload_bandwidth(size_t bytes) {
  Impl& m = *impl_;
  if (info_.emulated) return 0;  // PoCL's CPU device: "device" memory is host memory
  const cl_command_queue q = m.q(0);
  cl::Buffer host(m.cx->ctx(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, bytes, 0, m.align, q);
  cl::Buffer dev(m.cx->ctx(), CL_MEM_READ_WRITE, bytes, 0, m.align, q);
  cl_int e;
  void* p =
      clEnqueueMapBuffer(q, host.mem(), CL_TRUE, CL_MAP_WRITE, 0, bytes, 0, nullptr, nullptr, &e);
  cl::check(e, "clEnqueueMapBuffer (bandwidth)");
  std::memset(p, 1, bytes);
  double best = 0;
  for (int i = 0; i < 5; ++i) {
    std::vector<cl_event> ev;
    cl::write(q, dev.mem(), p, bytes, ev);
    cl::check(clFinish(q), "clFinish");
    const double s = cl::seconds(ev);
    if (s > 0) best = std::max(best, double(bytes) / s);
  }
  clEnqueueUnmapMemObject(q, host.mem(), p, 0, nullptr, nullptr);
  clFinish(q);
  return best;
}

}  // namespace rangex
