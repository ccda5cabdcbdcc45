// What the opencl backend holds on its device, and how it enqueues the line stages: the
// program and its kernels, the lanes' tables, the buffer groups (a batch of lines, a batch of
// fillets, a batch of dual-energy pixels) and the two batch slots, each on its own in-order
// queue. Shared by the backend's sources: opencl_backend.cpp (the device and the line
// batches), opencl_single_stages.cpp and opencl_fillet_stages.cpp.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "backends/device_lines.h"
#include "backends/lane_tables.h"
#include "backends/opencl/cl_runtime.h"
#include "backends/opencl/opencl_backend.h"
#include "shared/push_constants.h"

namespace rangex {

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

  // The fillet and dual-energy batches (opencl_fillet_stages.cpp).
  void ensure(Fillets& d, const FilletBatch& b);
  // Uploads a batch of fillets' inputs.
  void write_fillets(cl_command_queue qq, const FilletBatch& b, std::vector<cl_event>& up);
  void check_guards(const Fillets& d, cl_command_queue qq);
  void ensure(Pixels& d, size_t pixels);
  Pixels& begin_pixels(cl_command_queue qq, int pixels, const DualEnergyParams& k,
                       std::vector<cl_event>& up);
  void finish_pixels(cl_command_queue qq);

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
      cl::check(clEnqueueWriteBuffer(q(0), b.mem(), CL_TRUE, 0, n, p, 0, nullptr, nullptr),
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
    cl::write(qq, d.frames.mem(), host, bytes, up);
    return d.frames.mem();
  }

  void enqueue_stripes(cl_command_queue qq, Lines& d, cl_mem frames, int count,
                       std::vector<cl_event>& ev) {
    // A CPU device runs 16 columns per work-item as vector instructions; a GPU one column
    // per work-item (neighbouring work-items read neighbouring bytes).
    const bool by16 = cpu_device && tables.height <= 256 && tables.width % 16 == 0;
    const cl_kernel k = by16 ? k_stripe16 : k_stripe;
    cl::args(k, frames, count, tables.width, tables.height, d.frame_slot.mem(), t_stripe.mem(),
             t_ln.mem(), d.row.mem(), d.peak.mem(), d.width.mem(), d.asym.mem(), d.centroid.mem(),
             d.valid.mem());
    cl::launch(qq, k, size_t(count) * (by16 ? tables.width / 16 : tables.width), ev);
  }
  void enqueue_rectify(cl_command_queue qq, Lines& d, int count, std::vector<cl_event>& ev) {
    cl::args(k_rectify, d.row.mem(), d.valid.mem(), count, tables.width, d.frame_slot.mem(),
             t_rect.mem(), t_nodes.mem(), d.x.mem(), d.z.mem(), d.xz_valid.mem());
    cl::launch(qq, k_rectify, size_t(count) * tables.width, ev);
  }
  void enqueue_fuse(cl_command_queue qq, Lines& d, int lines, std::vector<cl_event>& ev) {
    cl::args(k_resample, d.x.mem(), d.z.mem(), d.xz_valid.mem(), tables.width, lines,
             d.lane_slot.mem(), t_geom.mem(), tables.grid_n, d.cam.mem());
    cl::launch(qq, k_resample, size_t(lines) * 2, ev);
    cl::args(k_merge, d.cam.mem(), lines, d.lane_slot.mem(), t_geom.mem(), tables.grid_n,
             d.profile.mem(), d.profile_valid.mem(), d.counts.mem(), d.top.mem());
    cl::launch(qq, k_merge, size_t(lines), ev);
  }
  void enqueue_project(cl_command_queue qq, Lines& d, int lines, std::vector<cl_event>& ev) {
    cl::args(k_project, d.profile.mem(), d.profile_valid.mem(), d.top.mem(), lines,
             d.lane_slot.mem(), t_geom.mem(), tables.grid_n, tables.pixels, d.thickness.mem(),
             d.thickness_valid.mem());
    cl::launch(qq, k_project, size_t(lines) * tables.pixels, ev);
  }

  void finish(cl_command_queue qq) { cl::check(clFinish(qq), "clFinish"); }
};

}  // namespace rangex
