#include "backends/opencl/opencl_backend.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "backends/device_lines.h"
#include "backends/lane_tables.h"
#include "backends/opencl/cl_runtime.h"
#include "core/error.h"
#include "kernels_cl.h"

namespace rangex {

namespace {

using cl::check;

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

void launch(cl_command_queue q, cl_kernel k, size_t n, std::vector<cl_event>& ev,
            size_t local = 0) {
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
    s += cl::event_seconds(e);
    clReleaseEvent(e);
  }
  ev.clear();
  return s;
}

void to_flags(const std::vector<int32_t>& in, size_t n, uint8_t* out) {
  for (size_t i = 0; i < n; ++i) out[i] = uint8_t(in[i] != 0);
}
std::vector<int32_t> from_flags(const uint8_t* in, size_t n) {
  std::vector<int32_t> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = in[i];
  return v;
}

}  // namespace

struct OpenClBackend::Impl {
  OpenClOptions opt;
  std::unique_ptr<cl::Context> cx;
  cl_program program = nullptr;
  cl_kernel k_stripe = nullptr, k_rectify = nullptr, k_resample = nullptr, k_merge = nullptr,
            k_project = nullptr, k_pseudo = nullptr, k_irls = nullptr, k_stripe16 = nullptr,
            k_dual = nullptr, k_bone = nullptr;
  bool cpu_device = false;
  size_t align = 128;
  KernelTables tables;
  cl::Buffer t_stripe, t_rect, t_nodes, t_geom, t_ln;

  // Device buffers for a batch of up to `lines` lines.
  using Lines = DeviceLines<cl::Buffer>;
  Lines scratch;  // single-stage calls

  // Buffers of a batch of fillets (pseudo-X-ray stages), grown as needed.
  struct Fillets {
    size_t pixels = 0;
    int fillets = 0;
    cl::Buffer thickness, xray, use, offsets, models, ln_p, p, residual, z, r, sums;
    std::vector<const cl::Buffer*> all() const {
      return {&thickness, &xray, &use, &offsets, &models, &ln_p, &p, &residual, &z, &r, &sums};
    }
  };
  Fillets fb;
  cl::Buffer t_ln_dn;  // ln(I) of every 16-bit DN, in double

  // Buffers of the dual-energy stages (a batch of pixels), grown as needed.
  struct Pixels {
    size_t pixels = 0;
    cl::Buffer low, high, open_low, open_high, thickness, use, params, basis, lengths, sigma, phi,
        phi_var, bone, bone_sigma;
    std::vector<const cl::Buffer*> all() const {
      return {&low,   &high,    &open_low, &open_high, &thickness, &use,  &params,
              &basis, &lengths, &sigma,    &phi,       &phi_var,   &bone, &bone_sigma};
    }
  };
  Pixels px;
  std::vector<uint8_t> every_pixel;  // use flags of a batch that has none

  // A dual-energy batch's buffers, grown to `pixels`, with the parameters' upload enqueued.
  Pixels& begin_pixels(cl_command_queue qq, int pixels, const DualEnergyParams& k,
                       std::vector<cl_event>& up) {
    ensure(px, size_t(pixels));
    write(qq, px.params.mem(), &k, sizeof k, up);
    return px;
  }
  void finish_pixels(cl_command_queue qq) {
    finish(qq);
    if (opt.guards)
      for (const cl::Buffer* x : px.all()) x->check_guards(qq, "dual energy");
  }

  void ensure(Pixels& d, size_t pixels) {
    const size_t n = std::max<size_t>(pixels, 1);
    if (!d.params.mem()) d.params = buffer(sizeof(kernel::DualEnergyK), CL_MEM_READ_ONLY);
    if (n <= d.pixels) return;
    for (cl::Buffer* x : {&d.low, &d.high}) *x = buffer(n * 2, CL_MEM_READ_ONLY);
    for (cl::Buffer* x : {&d.open_low, &d.open_high, &d.thickness, &d.phi, &d.phi_var})
      *x = buffer(n * 4, CL_MEM_READ_ONLY);
    d.use = buffer(n, CL_MEM_READ_ONLY);
    d.basis = buffer(n * 20);
    d.lengths = buffer(n * 12);
    d.sigma = buffer(n * 12);
    d.bone = buffer(n * 4);
    d.bone_sigma = buffer(n * 4);
    d.pixels = n;
  }

  void ensure(Fillets& d, const FilletBatch& b) {
    const size_t n = std::max<size_t>(size_t(b.pixels()), 1);
    if (n > d.pixels) {
      d.thickness = buffer(n * 4, CL_MEM_READ_ONLY);
      d.xray = buffer(n * 2, CL_MEM_READ_ONLY);
      d.use = buffer(n, CL_MEM_READ_ONLY);
      for (cl::Buffer* x : {&d.ln_p, &d.p, &d.residual, &d.z}) *x = buffer(n * 4);
      d.r = buffer(n * 8);
      d.pixels = n;
    }
    if (b.fillets > d.fillets) {
      d.offsets = buffer(size_t(b.fillets + 1) * 4, CL_MEM_READ_ONLY);
      d.models = buffer(size_t(b.fillets) * sizeof(kernel::FilletModelK), CL_MEM_READ_ONLY);
      d.sums = buffer(size_t(b.fillets) * IRLS_SUMS * 8);
      d.fillets = b.fillets;
    }
    if (!t_ln_dn.mem()) {
      std::vector<double> ln(65536);
      for (size_t i = 0; i < ln.size(); ++i) ln[i] = std::log(double(i));
      t_ln_dn = buffer(ln.size() * 8, CL_MEM_READ_ONLY);
      check(clEnqueueWriteBuffer(q(0), t_ln_dn.mem(), CL_TRUE, 0, ln.size() * 8, ln.data(), 0,
                                 nullptr, nullptr),
            "clEnqueueWriteBuffer (ln table)");
    }
  }
  // Uploads a batch of fillets' inputs.
  void write_fillets(cl_command_queue qq, const FilletBatch& b, std::vector<cl_event>& up) {
    check_fillet_batch(b);
    ensure(fb, b);
    const size_t n = size_t(b.pixels());
    write(qq, fb.thickness.mem(), b.thickness, n * 4, up);
    write(qq, fb.xray.mem(), b.xray, n * 2, up);
    write(qq, fb.use.mem(), b.use, n, up);
    write(qq, fb.offsets.mem(), b.offsets, size_t(b.fillets + 1) * 4, up);
    write(qq, fb.models.mem(), b.models, size_t(b.fillets) * sizeof(kernel::FilletModelK), up);
  }
  void check_guards(const Fillets& d, cl_command_queue qq) {
    if (!opt.guards) return;
    for (const cl::Buffer* x : d.all()) x->check_guards(qq, "fillets");
  }

  // A batch slot: pinned staging for frames and lane slots, the batch's device buffers and
  // the host side of its results.
  struct Slot final : LineBatchSlot {
    int queue = 0;
    bool busy = false, submitted = false;
    cl::Buffer pinned, view;
    std::vector<int32_t> lanes_host, frame_slot_host;
    Lines dev;
    std::vector<cl_event> up, run, down;
    LineReadback readback;
    void set(uint8_t* f, int32_t* l, int cap) {
      frames_ = f;
      lane_slot_ = l;
      capacity_ = cap;
    }
  };
  std::array<Slot, 2> slots;
  int next = 0;

  cl_command_queue q(int i) const { return cx->queue(i); }

  cl::Buffer buffer(size_t bytes, cl_mem_flags flags = CL_MEM_READ_WRITE) {
    return cl::Buffer(cx->ctx(), flags, bytes, opt.guards ? 256 : 0, align, q(0));
  }

  void ensure(Lines& d, int lines) {
    if (lines <= d.lines) return;
    d.each(LineExtents::of(tables, lines), [&](cl::Buffer& b, size_t bytes, bool input) {
      b = input ? buffer(bytes, CL_MEM_READ_ONLY) : buffer(bytes);
    });
    d.lines = lines;
  }

  void check_guards(Lines& d, cl_command_queue qq) {
    if (!opt.guards) return;
    for (cl::Buffer* b : d.all()) b->check_guards(qq, "batch");
    for (const cl::Buffer* b : {&t_stripe, &t_rect, &t_nodes, &t_geom, &t_ln})
      b->check_guards(qq, "tables");
  }

  void upload_tables() {
    auto up = [&](cl::Buffer& b, const void* p, size_t n) {
      b = buffer(std::max<size_t>(n, 4), CL_MEM_READ_ONLY);
      check(clEnqueueWriteBuffer(q(0), b.mem(), CL_TRUE, 0, n, p, 0, nullptr, nullptr),
            "clEnqueueWriteBuffer (tables)");
    };
    up(t_stripe, tables.stripe.data(), tables.stripe.size() * sizeof(kernel::StripeSlotK));
    up(t_rect, tables.rect.data(), tables.rect.size() * sizeof(kernel::RectTableK));
    up(t_nodes, tables.nodes.data(), tables.nodes.size() * 4);
    up(t_geom, tables.geom.data(), tables.geom.size() * sizeof(kernel::LaneGeomK));
    up(t_ln, tables.ln.data(), tables.ln.size() * 4);
  }

  // The stages, enqueued on queue qq over the device buffers d.
  // The frames as the stripe kernel reads them: on a CPU device a view of the host bytes
  // (kept alive in `view` until the kernel has run), on a GPU uploaded into d.frames.
  cl_mem frames_in(cl_command_queue qq, Lines& d, const uint8_t* host, size_t bytes,
                   cl::Buffer& view, std::vector<cl_event>& up) {
    if (cpu_device) {
      view = cl::Buffer(cx->ctx(), CL_MEM_READ_ONLY, bytes, host);
      return view.mem();
    }
    write(qq, d.frames.mem(), host, bytes, up);
    return d.frames.mem();
  }

  void enqueue_stripes(cl_command_queue qq, Lines& d, cl_mem frames, int count,
                       std::vector<cl_event>& ev) {
    // A CPU device runs 16 columns per work-item as vector instructions; a GPU one column
    // per work-item (neighbouring work-items read neighbouring bytes).
    const bool by16 = cpu_device && tables.height <= 256 && tables.width % 16 == 0;
    const cl_kernel k = by16 ? k_stripe16 : k_stripe;
    args(k, frames, count, tables.width, tables.height, d.frame_slot.mem(), t_stripe.mem(),
         t_ln.mem(), d.row.mem(), d.peak.mem(), d.width.mem(), d.asym.mem(), d.centroid.mem(),
         d.valid.mem());
    launch(qq, k, size_t(count) * (by16 ? tables.width / 16 : tables.width), ev);
  }
  void enqueue_rectify(cl_command_queue qq, Lines& d, int count, std::vector<cl_event>& ev) {
    args(k_rectify, d.row.mem(), d.valid.mem(), count, tables.width, d.frame_slot.mem(),
         t_rect.mem(), t_nodes.mem(), d.x.mem(), d.z.mem(), d.xz_valid.mem());
    launch(qq, k_rectify, size_t(count) * tables.width, ev);
  }
  void enqueue_fuse(cl_command_queue qq, Lines& d, int lines, std::vector<cl_event>& ev) {
    args(k_resample, d.x.mem(), d.z.mem(), d.xz_valid.mem(), tables.width, lines, d.lane_slot.mem(),
         t_geom.mem(), tables.grid_n, d.cam.mem());
    launch(qq, k_resample, size_t(lines) * 2, ev);
    args(k_merge, d.cam.mem(), lines, d.lane_slot.mem(), t_geom.mem(), tables.grid_n,
         d.profile.mem(), d.profile_valid.mem(), d.counts.mem(), d.top.mem());
    launch(qq, k_merge, size_t(lines), ev);
  }
  void enqueue_project(cl_command_queue qq, Lines& d, int lines, std::vector<cl_event>& ev) {
    args(k_project, d.profile.mem(), d.profile_valid.mem(), d.top.mem(), lines, d.lane_slot.mem(),
         t_geom.mem(), tables.grid_n, tables.pixels, d.thickness.mem(), d.thickness_valid.mem());
    launch(qq, k_project, size_t(lines) * tables.pixels, ev);
  }

  void finish(cl_command_queue qq) { check(clFinish(qq), "clFinish"); }
};

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
    check(e, (std::string("clCreateKernel ") + name).c_str());
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
    for (auto* v : {&s.up, &s.run, &s.down}) seconds(*v);
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
    check(e, "clEnqueueMapBuffer (staging)");
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
  write(qq, s.dev.frame_slot.mem(), s.frame_slot_host.data(), size_t(count) * 4, s.up);
  write(qq, s.dev.lane_slot.mem(), s.lane_slot(), size_t(lines) * 4, s.up);
  m.enqueue_stripes(qq, s.dev, frames, count, s.run);
  m.enqueue_rectify(qq, s.dev, count, s.run);
  m.enqueue_fuse(qq, s.dev, lines, s.run);
  m.enqueue_project(qq, s.dev, lines, s.run);
  check(clFlush(qq), "clFlush");
  s.submitted = true;
}

void OpenClBackend::collect(LineBatchSlot& batch, LineResults& out) {
  Impl& m = *impl_;
  auto& s = static_cast<Impl::Slot&>(batch);
  if (!s.submitted) submit(batch);
  const cl_command_queue qq = m.q(s.queue);
  const LineExtents e = LineExtents::of(m.tables, s.lines);
  const auto to = s.readback.prepare(e, out);
  s.dev.outputs(
      e, [&](cl::Buffer& b, size_t bytes, size_t k) { read(qq, b.mem(), to[k], bytes, s.down); });
  m.finish(qq);
  m.check_guards(s.dev, qq);
  s.readback.finish(out);
  times_ = {seconds(s.up), seconds(s.run), seconds(s.down)};
  s.busy = s.submitted = false;
}

// Single stages: inputs uploaded, one stage run, outputs read back, on queue 0.

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
  write(qq, m.scratch.frame_slot.mem(), frame_slot, size_t(count) * 4, up);
  m.enqueue_stripes(qq, m.scratch, in, count, run);
  out.resize(cols);
  std::vector<int32_t> valid(cols);
  read(qq, m.scratch.row.mem(), out.row.data(), cols * 4, down);
  read(qq, m.scratch.peak.mem(), out.peak.data(), cols * 4, down);
  read(qq, m.scratch.width.mem(), out.width.data(), cols * 4, down);
  read(qq, m.scratch.asym.mem(), out.asym.data(), cols * 4, down);
  read(qq, m.scratch.centroid.mem(), out.centroid.data(), cols * 4, down);
  read(qq, m.scratch.valid.mem(), valid.data(), cols * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(valid, cols, out.valid.data());
  times_ = {seconds(up), seconds(run), seconds(down)};
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
  write(qq, m.scratch.row.mem(), row, cols * 4, up);
  write(qq, m.scratch.valid.mem(), vin.data(), cols * 4, up);
  write(qq, m.scratch.frame_slot.mem(), frame_slot, size_t(count) * 4, up);
  m.enqueue_rectify(qq, m.scratch, count, run);
  read(qq, m.scratch.x.mem(), x, cols * 4, down);
  read(qq, m.scratch.z.mem(), z, cols * 4, down);
  read(qq, m.scratch.xz_valid.mem(), vout.data(), cols * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, cols, out_valid);
  times_ = {seconds(up), seconds(run), seconds(down)};
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
  write(qq, m.scratch.x.mem(), x, cols * 4, up);
  write(qq, m.scratch.z.mem(), z, cols * 4, up);
  write(qq, m.scratch.xz_valid.mem(), vin.data(), cols * 4, up);
  write(qq, m.scratch.lane_slot.mem(), lane_slot, size_t(lines) * 4, up);
  m.enqueue_fuse(qq, m.scratch, lines, run);
  read(qq, m.scratch.profile.mem(), profile, size_t(lines) * G * 4, down);
  read(qq, m.scratch.profile_valid.mem(), vout.data(), size_t(lines) * G * 4, down);
  read(qq, m.scratch.counts.mem(), counts.data(), size_t(lines) * sizeof(kernel::FusionCountK),
       down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, size_t(lines) * G, profile_valid);
  if (stats) add_fusion_counts(counts.data(), counts.size(), *stats);
  times_ = {seconds(up), seconds(run), seconds(down)};
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
  write(qq, m.scratch.profile.mem(), profile, size_t(lines) * G * 4, up);
  write(qq, m.scratch.profile_valid.mem(), vin.data(), size_t(lines) * G * 4, up);
  write(qq, m.scratch.top.mem(), top.data(), size_t(lines) * 4, up);
  write(qq, m.scratch.lane_slot.mem(), lane_slot, size_t(lines) * 4, up);
  m.enqueue_project(qq, m.scratch, lines, run);
  read(qq, m.scratch.thickness.mem(), thickness, size_t(lines) * P * 4, down);
  read(qq, m.scratch.thickness_valid.mem(), vout.data(), size_t(lines) * P * 4, down);
  m.finish(qq);
  m.check_guards(m.scratch, qq);
  to_flags(vout, size_t(lines) * P, thickness_valid);
  times_ = {seconds(up), seconds(run), seconds(down)};
}

}  // namespace rangex

namespace rangex {

double OpenClBackend::upload_bandwidth(size_t bytes) {
  Impl& m = *impl_;
  if (info_.emulated) return 0;  // PoCL's CPU device: "device" memory is host memory
  const cl_command_queue q = m.q(0);
  cl::Buffer host(m.cx->ctx(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, bytes, 0, m.align, q);
  cl::Buffer dev(m.cx->ctx(), CL_MEM_READ_WRITE, bytes, 0, m.align, q);
  cl_int e;
  void* p =
      clEnqueueMapBuffer(q, host.mem(), CL_TRUE, CL_MAP_WRITE, 0, bytes, 0, nullptr, nullptr, &e);
  check(e, "clEnqueueMapBuffer (bandwidth)");
  std::memset(p, 1, bytes);
  double best = 0;
  for (int i = 0; i < 5; ++i) {
    std::vector<cl_event> ev;
    write(q, dev.mem(), p, bytes, ev);
    check(clFinish(q), "clFinish");
    const double s = seconds(ev);
    if (s > 0) best = std::max(best, double(bytes) / s);
  }
  clEnqueueUnmapMemObject(q, host.mem(), p, 0, nullptr, nullptr);
  clFinish(q);
  return best;
}

}  // namespace rangex

namespace rangex {

namespace {
constexpr size_t kFilletGroup = 256;  // work-items per fillet (a power of two: the reduction)
}  // namespace

void OpenClBackend::pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                                float* z) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  m.write_fillets(qq, b, up);
  Impl::Fillets& d = m.fb;
  args(m.k_pseudo, d.thickness.mem(), d.xray.mem(), d.use.mem(), d.offsets.mem(), d.models.mem(),
       m.t_ln_dn.mem(), d.ln_p.mem(), d.p.mem(), d.residual.mem(), d.z.mem());
  launch(qq, m.k_pseudo, size_t(b.fillets) * kFilletGroup, run, kFilletGroup);
  const size_t n = size_t(b.pixels());
  read(qq, d.ln_p.mem(), ln_p, n * 4, down);
  read(qq, d.p.mem(), p, n * 4, down);
  read(qq, d.residual.mem(), residual, n * 4, down);
  read(qq, d.z.mem(), z, n * 4, down);
  m.finish(qq);
  m.check_guards(d, qq);
  times_ = {seconds(up), seconds(run), seconds(down)};
}

void OpenClBackend::irls_sums(const FilletBatch& b, double* r, double* sums) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  m.write_fillets(qq, b, up);
  Impl::Fillets& d = m.fb;
  args(m.k_irls, d.thickness.mem(), d.xray.mem(), d.use.mem(), d.offsets.mem(), d.models.mem(),
       m.t_ln_dn.mem(), d.r.mem(), d.sums.mem());
  check(clSetKernelArg(m.k_irls, 8, kFilletGroup * IRLS_SUMS * sizeof(double), nullptr),
        "clSetKernelArg (local sums)");
  launch(qq, m.k_irls, size_t(b.fillets) * kFilletGroup, run, kFilletGroup);
  read(qq, d.r.mem(), r, size_t(b.pixels()) * 8, down);
  read(qq, d.sums.mem(), sums, size_t(b.fillets) * IRLS_SUMS * 8, down);
  m.finish(qq);
  m.check_guards(d, qq);
  times_ = {seconds(up), seconds(run), seconds(down)};
}

void OpenClBackend::dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                                float* lengths, float* sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  Impl::Pixels& d = m.begin_pixels(qq, b.pixels, k, up);
  const size_t n = size_t(b.pixels);
  const uint8_t* use = b.use;
  if (!use) {
    m.every_pixel.assign(n, 1);
    use = m.every_pixel.data();
  }
  write(qq, d.low.mem(), b.low, n * 2, up);
  write(qq, d.high.mem(), b.high, n * 2, up);
  write(qq, d.open_low.mem(), b.open_low, n * 4, up);
  write(qq, d.open_high.mem(), b.open_high, n * 4, up);
  write(qq, d.thickness.mem(), b.thickness, n * 4, up);
  write(qq, d.use.mem(), use, n, up);
  args(m.k_dual, d.low.mem(), d.high.mem(), d.open_low.mem(), d.open_high.mem(), d.thickness.mem(),
       d.use.mem(), d.params.mem(), cl_int(b.pixels), d.basis.mem(), d.lengths.mem(),
       d.sigma.mem());
  launch(qq, m.k_dual, n, run);
  read(qq, d.basis.mem(), basis, n * 20, down);
  read(qq, d.lengths.mem(), lengths, n * 12, down);
  read(qq, d.sigma.mem(), sigma, n * 12, down);
  m.finish_pixels(qq);
  times_ = {seconds(up), seconds(run), seconds(down)};
}

void OpenClBackend::dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k,
                                     float* bone, float* bone_sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  const cl_command_queue qq = m.q(0);
  std::vector<cl_event> up, run, down;
  Impl::Pixels& d = m.begin_pixels(qq, b.pixels, k, up);
  const size_t n = size_t(b.pixels);
  write(qq, d.basis.mem(), b.basis, n * 20, up);
  write(qq, d.thickness.mem(), b.thickness, n * 4, up);
  write(qq, d.phi.mem(), b.phi, n * 4, up);
  write(qq, d.phi_var.mem(), b.phi_var, n * 4, up);
  args(m.k_bone, d.basis.mem(), d.thickness.mem(), d.phi.mem(), d.phi_var.mem(), d.params.mem(),
       cl_int(b.pixels), cl_double(b.density_var), d.bone.mem(), d.bone_sigma.mem());
  launch(qq, m.k_bone, n, run);
  read(qq, d.bone.mem(), bone, n * 4, down);
  read(qq, d.bone_sigma.mem(), bone_sigma, n * 4, down);
  m.finish_pixels(qq);
  times_ = {seconds(up), seconds(run), seconds(down)};
}

}  // namespace rangex
