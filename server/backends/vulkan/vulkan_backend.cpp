#include "backends/vulkan/vulkan_backend.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>

#include "backends/device_lines.h"
#include "backends/lane_tables.h"
#include "backends/vulkan/vk_runtime.h"
#include "core/error.h"
#include "shaders_spv.h"
#include "shared/push_constants.h"

namespace rangex {

using vk::check;

std::vector<VulkanDevice> vulkan_devices() {
  // No loader or driver throws, naming what failed: a probe tells that from a device that
  // lacks a feature.
  std::vector<VulkanDevice> out;
  vk::Instance inst;
  for (const auto& d : inst.devices()) out.push_back({d.name, d.cpu});
  return out;
}

namespace {

enum K {
  kStripe,
  kRectify,
  kResample,
  kMerge,
  kProject,
  kPseudo,
  kIrls,
  kDualEnergy,
  kDualEnergyBone,
  kKernels
};

static_assert(sizeof(kernel::DualEnergyK) == 512, "the std430 layout of shared/dual_energy.h");

// An array the shaders use: on the device, and (when the device's memory is not mappable)
// a host mirror that inputs are written to and results read from, copied in the command
// buffer.
struct Arr {
  vk::Buffer dev, host;
  bool mirrored = false;
  uint8_t* ptr() const { return mirrored ? host.data() : dev.data(); }
};

void barrier(VkCommandBuffer cb, VkPipelineStageFlags src, VkAccessFlags src_access,
             VkPipelineStageFlags dst, VkAccessFlags dst_access) {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = src_access;
  mb.dstAccessMask = dst_access;
  vkCmdPipelineBarrier(cb, src, dst, 0, 1, &mb, 0, nullptr, 0, nullptr);
}

void to_flags(const uint8_t* in, size_t n, uint8_t* out) {
  const int32_t* v = reinterpret_cast<const int32_t*>(in);
  for (size_t i = 0; i < n; ++i) out[i] = uint8_t(v[i] != 0);
}
void from_flags(const uint8_t* in, size_t n, uint8_t* out) {
  int32_t* v = reinterpret_cast<int32_t*>(out);
  for (size_t i = 0; i < n; ++i) v[i] = in[i];
}

}  // namespace

struct VulkanBackend::Impl {
  VulkanOptions opt;
  std::unique_ptr<vk::Instance> inst;
  std::unique_ptr<vk::Device> dev;
  std::array<vk::Kernel, kKernels> k;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkCommandPool cmd_pool = VK_NULL_HANDLE;
  VkQueryPool queries = VK_NULL_HANDLE;
  double tick_ns = 0;  // 0: no timestamps on this queue
  KernelTables tables;
  vk::Buffer t_stripe, t_rect, t_nodes, t_geom, t_ln;

  // Buffers, descriptor sets, a command buffer and a fence for a batch of up to `lines`.
  struct Lines : DeviceLines<Arr> {
    int index = 0;  // its four timestamps start at 4 * index
    std::array<VkDescriptorSet, kKernels> sets{};
    VkCommandBuffer cb = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;
  };
  struct Slot final : LineBatchSlot {
    Lines* lines_buf = nullptr;
    bool busy = false, submitted = false;
    LineReadback readback;
    void point(int cap) {
      frames_ = lines_buf->frames.ptr();
      lane_slot_ = reinterpret_cast<int32_t*>(lines_buf->lane_slot.ptr());
      capacity_ = cap;
    }
  };
  std::array<Lines, 3> lines_bufs;  // two batch slots and the single-stage scratch

  // Buffers of a batch of fillets (pseudo-X-ray stages), grown as needed; their commands
  // run on the scratch command buffer with its descriptor sets for kPseudo and kIrls.
  struct Fillets {
    size_t pixels = 0;
    int fillets = 0;
    Arr thickness, xray, use, offsets, models, ln_p, p, residual, z, r, sums;
    std::vector<Arr*> all() {
      return {&thickness, &xray, &use, &offsets, &models, &ln_p, &p, &residual, &z, &r, &sums};
    }
  };
  Fillets fb;
  vk::Buffer t_ln_dn;  // ln(I) of every 16-bit DN, in double

  // Buffers of the dual-energy stages (a batch of pixels), grown as needed; their commands
  // run on the scratch command buffer with its descriptor sets for kDualEnergy(Bone).
  struct Pixels {
    size_t pixels = 0;
    Arr low, high, open_low, open_high, thickness, use, params, basis, lengths, sigma, phi, phi_var,
        bone, bone_sigma;
    std::vector<Arr*> all() {
      return {&low,   &high,    &open_low, &open_high, &thickness, &use,  &params,
              &basis, &lengths, &sigma,    &phi,       &phi_var,   &bone, &bone_sigma};
    }
  };
  Pixels px;

  void ensure(Pixels& d, size_t pixels) {
    const size_t n = std::max<size_t>(pixels, 4);
    if (n <= d.pixels) return;
    for (Arr* a : d.all()) free(*a);
    d.low = array((n * 2 + 3) / 4 * 4);
    d.high = array((n * 2 + 3) / 4 * 4);
    for (Arr* a :
         {&d.open_low, &d.open_high, &d.thickness, &d.phi, &d.phi_var, &d.bone, &d.bone_sigma})
      *a = array(n * 4);
    d.use = array((n + 3) / 4 * 4);
    d.params = array(sizeof(kernel::DualEnergyK));
    d.basis = array(n * 20);
    d.lengths = array(n * 12);
    d.sigma = array(n * 12);
    d.pixels = n;
    Lines& s = lines_bufs[2];
    write_set(s.sets[kDualEnergy],
              {&d.low.dev, &d.high.dev, &d.open_low.dev, &d.open_high.dev, &d.thickness.dev,
               &d.use.dev, &d.params.dev, &d.basis.dev, &d.lengths.dev, &d.sigma.dev});
    write_set(s.sets[kDualEnergyBone], {&d.basis.dev, &d.thickness.dev, &d.phi.dev, &d.phi_var.dev,
                                        &d.params.dev, &d.bone.dev, &d.bone_sigma.dev});
  }
  // A dual-energy batch's buffers, grown to `pixels`, with the parameters written.
  Pixels& begin_pixels(int pixels, const DualEnergyParams& k) {
    ensure(px, size_t(pixels));
    std::memcpy(px.params.ptr(), &k, sizeof k);
    return px;
  }
  // Runs one dual-energy stage on the scratch command buffer: `ins` copied in, the stage,
  // `outs` copied out, waited for.
  void run_pixels(K which, const kernel::DualEnergyPush& push,
                  std::initializer_list<std::pair<Arr*, VkDeviceSize>> ins,
                  const std::vector<std::pair<Arr*, VkDeviceSize>>& outs) {
    Lines& s = lines_bufs[2];
    begin(s);
    stamp(s, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    copy_in(s, ins);
    stamp(s, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
    dispatch(s, which, &push, uint32_t(push.pixels));
    stamp(s, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    copy_out(s, outs);
    stamp(s, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    end_and_submit(s);
    wait(s);
    if (opt.guards)
      for (Arr* a : px.all()) dev->check_guards(a->dev, "dual energy");
  }

  void ensure(Fillets& d, const FilletBatch& b) {
    const size_t n = std::max<size_t>(size_t(b.pixels()), 4);
    bool changed = false;
    if (n > d.pixels) {
      for (Arr* a : {&d.thickness, &d.xray, &d.use, &d.ln_p, &d.p, &d.residual, &d.z, &d.r})
        free(*a);
      d.thickness = array(n * 4);
      d.xray = array((n * 2 + 3) / 4 * 4);
      d.use = array((n + 3) / 4 * 4);
      for (Arr* a : {&d.ln_p, &d.p, &d.residual, &d.z}) *a = array(n * 4);
      d.r = array(n * 8);
      d.pixels = n;
      changed = true;
    }
    if (b.fillets > d.fillets) {
      for (Arr* a : {&d.offsets, &d.models, &d.sums}) free(*a);
      d.offsets = array(size_t(b.fillets + 1) * 4);
      d.models = array(size_t(b.fillets) * sizeof(kernel::FilletModelK));
      d.sums = array(size_t(b.fillets) * IRLS_SUMS * 8);
      d.fillets = b.fillets;
      changed = true;
    }
    if (!t_ln_dn.buf) {
      std::vector<double> ln(65536);
      for (size_t i = 0; i < ln.size(); ++i) ln[i] = std::log(double(i));
      upload(t_ln_dn, ln.data(), ln.size() * 8);
      changed = true;
    }
    if (!changed) return;
    Lines& s = lines_bufs[2];
    write_set(s.sets[kPseudo],
              {&d.thickness.dev, &d.xray.dev, &d.use.dev, &d.offsets.dev, &d.models.dev, &t_ln_dn,
               &d.ln_p.dev, &d.p.dev, &d.residual.dev, &d.z.dev});
    write_set(s.sets[kIrls], {&d.thickness.dev, &d.xray.dev, &d.use.dev, &d.offsets.dev,
                              &d.models.dev, &t_ln_dn, &d.r.dev, &d.sums.dev});
  }
  // Writes a batch of fillets' inputs into the arrays (their host side) and records the
  // copies to the device; returns the scratch command buffer's batch, begun.
  Lines& begin_fillets(const FilletBatch& b) {
    check_fillet_batch(b);
    Fillets& d = fb;
    ensure(d, b);
    const size_t n = size_t(b.pixels());
    std::memcpy(d.thickness.ptr(), b.thickness, n * 4);
    std::memcpy(d.xray.ptr(), b.xray, n * 2);
    std::memcpy(d.use.ptr(), b.use, n);
    std::memcpy(d.offsets.ptr(), b.offsets, size_t(b.fillets + 1) * 4);
    std::memcpy(d.models.ptr(), b.models, size_t(b.fillets) * sizeof(kernel::FilletModelK));
    Lines& s = lines_bufs[2];
    begin(s);
    stamp(s, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    copy_in(s, {{&d.thickness, VkDeviceSize(n * 4)},
                {&d.xray, VkDeviceSize((n * 2 + 3) / 4 * 4)},
                {&d.use, VkDeviceSize((n + 3) / 4 * 4)},
                {&d.offsets, VkDeviceSize(b.fillets + 1) * 4},
                {&d.models, VkDeviceSize(b.fillets) * sizeof(kernel::FilletModelK)}});
    stamp(s, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
    return s;
  }
  void dispatch_fillets(Lines& s, K which, int fillets) {
    const vk::Kernel& kk = k[which];
    const kernel::FilletPush push{fillets, 0, 0, 0};
    vkCmdBindPipeline(s.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.pipeline);
    vkCmdBindDescriptorSets(s.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.layout, 0, 1, &s.sets[which],
                            0, nullptr);
    vkCmdPushConstants(s.cb, kk.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, kk.push_bytes, &push);
    vkCmdDispatch(s.cb, uint32_t(fillets), 1, 1);
    stamp(s, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  }
  void finish_fillets(Lines& s) {
    stamp(s, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
    end_and_submit(s);
    wait(s);
    if (opt.guards)
      for (Arr* a : fb.all()) dev->check_guards(a->dev, "fillets");
  }
  std::array<Slot, 2> slots;
  int next = 0;

  VkDeviceSize guard() const { return opt.guards ? 256 : 0; }

  Arr array(VkDeviceSize bytes) {
    Arr a;
    a.dev = dev->buffer(bytes, false, guard());
    if (!a.dev.map) {
      a.mirrored = true;
      a.host = dev->buffer(bytes, true);
    }
    return a;
  }
  void free(Arr& a) {
    dev->destroy(a.dev);
    dev->destroy(a.host);
    a.mirrored = false;
  }

  void write_set(VkDescriptorSet set, const std::vector<const vk::Buffer*>& bufs) {
    std::vector<VkDescriptorBufferInfo> infos(bufs.size());
    std::vector<VkWriteDescriptorSet> w(bufs.size());
    for (size_t i = 0; i < bufs.size(); ++i) {
      infos[i] = {bufs[i]->buf, bufs[i]->offset, bufs[i]->bytes};
      w[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w[i].dstSet = set;
      w[i].dstBinding = uint32_t(i);
      w[i].descriptorCount = 1;
      w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w[i].pBufferInfo = &infos[i];
    }
    vkUpdateDescriptorSets(dev->get(), uint32_t(w.size()), w.data(), 0, nullptr);
  }

  void update_sets(Lines& d) {
    if (!d.lines || !t_stripe.buf) return;
    write_set(d.sets[kStripe],
              {&d.frames.dev, &d.frame_slot.dev, &t_stripe, &t_ln, &d.row.dev, &d.peak.dev,
               &d.width.dev, &d.asym.dev, &d.centroid.dev, &d.valid.dev});
    write_set(d.sets[kRectify], {&d.row.dev, &d.valid.dev, &d.frame_slot.dev, &t_rect, &t_nodes,
                                 &d.x.dev, &d.z.dev, &d.xz_valid.dev});
    write_set(d.sets[kResample],
              {&d.x.dev, &d.z.dev, &d.xz_valid.dev, &d.lane_slot.dev, &t_geom, &d.cam.dev});
    write_set(d.sets[kMerge], {&d.cam.dev, &d.lane_slot.dev, &t_geom, &d.profile.dev,
                               &d.profile_valid.dev, &d.counts.dev, &d.top.dev});
    write_set(d.sets[kProject], {&d.profile.dev, &d.profile_valid.dev, &d.top.dev, &d.lane_slot.dev,
                                 &t_geom, &d.thickness.dev, &d.thickness_valid.dev});
  }

  void ensure(Lines& d, int lines) {
    if (lines <= d.lines) return;
    for (Arr* a : d.all()) free(*a);
    d.each(LineExtents::of(tables, lines),
           [&](Arr& a, size_t bytes, bool) { a = array(VkDeviceSize(bytes)); });
    d.lines = lines;
    update_sets(d);
  }

  void check_guards(Lines& d) {
    if (!opt.guards) return;
    for (Arr* a : d.all()) dev->check_guards(a->dev, "batch");
    for (const vk::Buffer* b : {&t_stripe, &t_rect, &t_nodes, &t_geom, &t_ln})
      dev->check_guards(*b, "tables");
  }

  // Runs commands recorded by `record` once, on the scratch command buffer, and waits.
  template <typename F>
  void once(F&& record) {
    Lines& s = lines_bufs[2];
    begin(s);
    record(s.cb);
    end_and_submit(s);
    wait(s);
  }

  void upload(vk::Buffer& dst, const void* src, size_t bytes) {
    dev->destroy(dst);
    dst = dev->buffer(std::max<size_t>(bytes, 4), false, guard());
    if (dst.map) {
      std::memcpy(dst.data(), src, bytes);
      return;
    }
    vk::Buffer stage = dev->buffer(bytes, true);
    std::memcpy(stage.data(), src, bytes);
    once([&](VkCommandBuffer cb) {
      VkBufferCopy r{stage.offset, dst.offset, bytes};
      vkCmdCopyBuffer(cb, stage.buf, dst.buf, 1, &r);
    });
    dev->destroy(stage);
  }

  void upload_tables() {
    upload(t_stripe, tables.stripe.data(), tables.stripe.size() * sizeof(kernel::StripeSlotK));
    upload(t_rect, tables.rect.data(), tables.rect.size() * sizeof(kernel::RectTableK));
    upload(t_nodes, tables.nodes.data(), tables.nodes.size() * 4);
    upload(t_geom, tables.geom.data(), tables.geom.size() * sizeof(kernel::LaneGeomK));
    upload(t_ln, tables.ln.data(), tables.ln.size() * 4);
    for (Lines& d : lines_bufs) update_sets(d);
  }

  void begin(Lines& d) {
    check(vkResetCommandBuffer(d.cb, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(d.cb, &bi), "vkBeginCommandBuffer");
    if (tick_ns) vkCmdResetQueryPool(d.cb, queries, uint32_t(4 * d.index), 4);
  }
  void stamp(Lines& d, int i, VkPipelineStageFlagBits stage) {
    if (tick_ns) vkCmdWriteTimestamp(d.cb, stage, queries, uint32_t(4 * d.index + i));
  }
  void end_and_submit(Lines& d) {
    check(vkEndCommandBuffer(d.cb), "vkEndCommandBuffer");
    check(vkResetFences(dev->get(), 1, &d.fence), "vkResetFences");
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &d.cb;
    check(vkQueueSubmit(dev->queue(), 1, &si, d.fence), "vkQueueSubmit");
  }
  void wait(Lines& d) {
    check(vkWaitForFences(dev->get(), 1, &d.fence, VK_TRUE, uint64_t(60) * 1000000000ull),
          "vkWaitForFences");
  }
  StageTimes times(Lines& d) {
    if (!tick_ns) return {};
    uint64_t t[4];
    if (vkGetQueryPoolResults(dev->get(), queries, uint32_t(4 * d.index), 4, sizeof t, t,
                              sizeof(uint64_t), VK_QUERY_RESULT_64_BIT) != VK_SUCCESS)
      return {};
    return {double(t[1] - t[0]) * tick_ns * 1e-9, double(t[2] - t[1]) * tick_ns * 1e-9,
            double(t[3] - t[2]) * tick_ns * 1e-9};
  }

  // Host mirrors of `ins` to the device, before the dispatches.
  void copy_in(Lines& d, std::initializer_list<std::pair<Arr*, VkDeviceSize>> ins) {
    bool any = false;
    for (auto [a, n] : ins)
      if (a->mirrored && n) {
        VkBufferCopy r{a->host.offset, a->dev.offset, n};
        vkCmdCopyBuffer(d.cb, a->host.buf, a->dev.buf, 1, &r);
        any = true;
      }
    if (any)
      barrier(d.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
              VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
  }
  // Results of the dispatches to their host mirrors, then visible to the host.
  void copy_out(Lines& d, const std::vector<std::pair<Arr*, VkDeviceSize>>& outs) {
    barrier(d.cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_HOST_READ_BIT);
    for (auto [a, n] : outs)
      if (a->mirrored && n) {
        VkBufferCopy r{a->dev.offset, a->host.offset, n};
        vkCmdCopyBuffer(d.cb, a->dev.buf, a->host.buf, 1, &r);
      }
    barrier(d.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
            VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
  }

  void dispatch(Lines& d, K which, const void* push, uint32_t n) {
    if (n == 0) return;
    const vk::Kernel& kk = k[which];
    vkCmdBindPipeline(d.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.pipeline);
    vkCmdBindDescriptorSets(d.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.layout, 0, 1, &d.sets[which],
                            0, nullptr);
    vkCmdPushConstants(d.cb, kk.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, kk.push_bytes, push);
    vkCmdDispatch(d.cb, (n + 63) / 64, 1, 1);
  }
  void between(Lines& d) {
    barrier(d.cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
            VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
            VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
  }
  void record_stripes(Lines& d, int count) {
    const kernel::StripePush p{count, tables.width, tables.height, 0};
    dispatch(d, kStripe, &p, uint32_t(count) * uint32_t(tables.width));
  }
  void record_rectify(Lines& d, int count) {
    const kernel::RectifyPush p{count, tables.width, 0, 0};
    dispatch(d, kRectify, &p, uint32_t(count) * uint32_t(tables.width));
  }
  void record_fuse(Lines& d, int lines) {
    const kernel::FusePush p{lines, tables.width, tables.grid_n, 0};
    dispatch(d, kResample, &p, uint32_t(lines) * 2);
    between(d);
    dispatch(d, kMerge, &p, uint32_t(lines));
  }
  void record_project(Lines& d, int lines) {
    const kernel::ProjectPush p{lines, tables.grid_n, tables.pixels, 0};
    dispatch(d, kProject, &p, uint32_t(lines) * uint32_t(tables.pixels));
  }
};

VulkanBackend::VulkanBackend(const VulkanOptions& opt) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.opt = opt;
  m.inst = std::make_unique<vk::Instance>();
  const vk::DeviceChoice d = m.inst->choose(opt.device);
  m.dev = std::make_unique<vk::Device>(*m.inst, d);
  VkDevice dv = m.dev->get();
  m.k[kStripe] = vk::make_kernel(*m.dev, shaders::kStripe, sizeof shaders::kStripe, 10,
                                 sizeof(kernel::StripePush));
  m.k[kRectify] = vk::make_kernel(*m.dev, shaders::kRectify, sizeof shaders::kRectify, 8,
                                  sizeof(kernel::RectifyPush));
  m.k[kResample] = vk::make_kernel(*m.dev, shaders::kFuseResample, sizeof shaders::kFuseResample, 6,
                                   sizeof(kernel::FusePush));
  m.k[kMerge] = vk::make_kernel(*m.dev, shaders::kFuseMerge, sizeof shaders::kFuseMerge, 7,
                                sizeof(kernel::FusePush));
  m.k[kProject] = vk::make_kernel(*m.dev, shaders::kProject, sizeof shaders::kProject, 7,
                                  sizeof(kernel::ProjectPush));
  m.k[kPseudo] = vk::make_kernel(*m.dev, shaders::kPseudoXray, sizeof shaders::kPseudoXray, 10,
                                 sizeof(kernel::FilletPush));
  m.k[kIrls] = vk::make_kernel(*m.dev, shaders::kIrlsSums, sizeof shaders::kIrlsSums, 8,
                               sizeof(kernel::FilletPush));
  m.k[kDualEnergy] = vk::make_kernel(*m.dev, shaders::kDualEnergy, sizeof shaders::kDualEnergy, 10,
                                     sizeof(kernel::DualEnergyPush));
  m.k[kDualEnergyBone] =
      vk::make_kernel(*m.dev, shaders::kDualEnergyBone, sizeof shaders::kDualEnergyBone, 7,
                      sizeof(kernel::DualEnergyPush));
  m.dev->save_cache();
  // Descriptor sets for the three buffer groups, allocated once and updated when buffers
  // or tables change (never while a batch that uses them is in flight).
  VkDescriptorPoolSize ps{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                          3 * (10 + 8 + 6 + 7 + 7 + 10 + 8 + 10 + 7)};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = 3 * kKernels;
  pi.poolSizeCount = 1;
  pi.pPoolSizes = &ps;
  check(vkCreateDescriptorPool(dv, &pi, nullptr, &m.pool), "vkCreateDescriptorPool");
  VkCommandPoolCreateInfo cpi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  cpi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  cpi.queueFamilyIndex = m.dev->family();
  check(vkCreateCommandPool(dv, &cpi, nullptr, &m.cmd_pool), "vkCreateCommandPool");
  uint32_t nq = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(d.physical, &nq, nullptr);
  std::vector<VkQueueFamilyProperties> qs(nq);
  vkGetPhysicalDeviceQueueFamilyProperties(d.physical, &nq, qs.data());
  if (qs[m.dev->family()].timestampValidBits > 0 && d.props.limits.timestampPeriod > 0) {
    VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qi.queryCount = 12;
    check(vkCreateQueryPool(dv, &qi, nullptr, &m.queries), "vkCreateQueryPool");
    m.tick_ns = d.props.limits.timestampPeriod;
  }
  for (int i = 0; i < 3; ++i) {
    Impl::Lines& L = m.lines_bufs[i];
    L.index = i;
    for (int kk = 0; kk < kKernels; ++kk) {
      VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
      ai.descriptorPool = m.pool;
      ai.descriptorSetCount = 1;
      ai.pSetLayouts = &m.k[kk].set_layout;
      check(vkAllocateDescriptorSets(dv, &ai, &L.sets[kk]), "vkAllocateDescriptorSets");
    }
    VkCommandBufferAllocateInfo ci{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ci.commandPool = m.cmd_pool;
    ci.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ci.commandBufferCount = 1;
    check(vkAllocateCommandBuffers(dv, &ci, &L.cb), "vkAllocateCommandBuffers");
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(vkCreateFence(dv, &fi, nullptr, &L.fence), "vkCreateFence");
  }
  for (int i = 0; i < 2; ++i) m.slots[i].lines_buf = &m.lines_bufs[i];
  info_.name = "vulkan";
  info_.device = d.name;
  info_.driver = "Vulkan " + std::to_string(VK_API_VERSION_MAJOR(d.props.apiVersion)) + "." +
                 std::to_string(VK_API_VERSION_MINOR(d.props.apiVersion)) + "." +
                 std::to_string(VK_API_VERSION_PATCH(d.props.apiVersion)) + ", driver " +
                 std::to_string(d.props.driverVersion);
  info_.emulated = d.cpu;
  info_.overlaps = true;
  info_.limits =
      std::string(m.dev->unified() ? "unified" : "device") + " memory, buffers up to " +
      std::to_string(d.props.limits.maxStorageBufferRange >> 20) + " MiB, work-groups of " +
      std::to_string(d.props.limits.maxComputeWorkGroupInvocations) + "; " + m.dev->cache_note();
}

VulkanBackend::~VulkanBackend() {
  Impl& m = *impl_;
  if (!m.dev) return;
  VkDevice dv = m.dev->get();
  vkDeviceWaitIdle(dv);
  for (Impl::Lines& L : m.lines_bufs) {
    for (Arr* a : L.all()) m.free(*a);
    if (L.fence) vkDestroyFence(dv, L.fence, nullptr);
  }
  for (vk::Buffer* b : {&m.t_stripe, &m.t_rect, &m.t_nodes, &m.t_geom, &m.t_ln, &m.t_ln_dn})
    m.dev->destroy(*b);
  for (Arr* a : m.fb.all()) m.free(*a);
  for (Arr* a : m.px.all()) m.free(*a);
  if (m.queries) vkDestroyQueryPool(dv, m.queries, nullptr);
  if (m.cmd_pool) vkDestroyCommandPool(dv, m.cmd_pool, nullptr);
  if (m.pool) vkDestroyDescriptorPool(dv, m.pool, nullptr);
  for (auto& kk : m.k) vk::destroy(*m.dev, kk);
}

void VulkanBackend::set_lanes(const std::vector<LaneConfig>& lanes) {
  Impl& m = *impl_;
  for (const auto& s : m.slots)
    if (s.busy) fail("backend vulkan: lanes changed with a batch in flight");
  m.tables.set_lanes(lanes);
  for (Impl::Lines& L : m.lines_bufs) {  // sizes may have changed
    for (Arr* a : L.all()) m.free(*a);
    L.lines = 0;
  }
  m.upload_tables();
  lanes_ = lanes;
}

void VulkanBackend::update_lane(int slot, const LaneConfig& lane) {
  Impl& m = *impl_;
  for (const auto& s : m.slots)
    if (s.busy) fail("backend vulkan: a lane changed with a batch in flight");
  m.tables.update_lane(slot, lane);
  m.upload_tables();
  lanes_.at(slot) = lane;
}

LineBatchSlot& VulkanBackend::acquire(int lines) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  // The free slot (batches may be collected in any order).
  if (m.slots[m.next].busy) m.next = 1 - m.next;
  Impl::Slot& s = m.slots[m.next];
  if (s.busy) fail("backend vulkan: both staging slots are in flight; collect one first");
  m.next = 1 - m.next;
  m.ensure(*s.lines_buf, lines);
  s.point(s.lines_buf->lines);
  s.lines = lines;
  s.busy = true;
  s.submitted = false;
  return s;
}

void VulkanBackend::submit(LineBatchSlot& batch) {
  Impl& m = *impl_;
  auto& s = static_cast<Impl::Slot&>(batch);
  Impl::Lines& d = *s.lines_buf;
  const int lines = s.lines, count = lines * 2;
  int32_t* fs = reinterpret_cast<int32_t*>(d.frame_slot.ptr());
  for (int l = 0; l < lines; ++l) {
    if (s.lane_slot()[l] < 0 || s.lane_slot()[l] >= int(lanes_.size()))
      fail("line ", l, " of the batch names lane slot ", s.lane_slot()[l], " which does not exist");
    fs[2 * l] = s.lane_slot()[l] * 2;
    fs[2 * l + 1] = s.lane_slot()[l] * 2 + 1;
  }
  const VkDeviceSize W = VkDeviceSize(m.tables.width);
  m.begin(d);
  m.stamp(d, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  m.copy_in(d, {{&d.frames, VkDeviceSize(count) * W * VkDeviceSize(m.tables.height)},
                {&d.frame_slot, VkDeviceSize(count) * 4},
                {&d.lane_slot, VkDeviceSize(lines) * 4}});
  m.stamp(d, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
  m.record_stripes(d, count);
  m.between(d);
  m.record_rectify(d, count);
  m.between(d);
  m.record_fuse(d, lines);
  m.between(d);
  m.record_project(d, lines);
  m.stamp(d, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  std::vector<std::pair<Arr*, VkDeviceSize>> outs;
  d.outputs(LineExtents::of(m.tables, lines),
            [&](Arr& a, size_t bytes, size_t) { outs.emplace_back(&a, VkDeviceSize(bytes)); });
  m.copy_out(d, outs);
  m.stamp(d, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  m.end_and_submit(d);
  s.submitted = true;
}

void VulkanBackend::collect(LineBatchSlot& batch, LineResults& out) {
  Impl& m = *impl_;
  auto& s = static_cast<Impl::Slot&>(batch);
  if (!s.submitted) submit(batch);
  Impl::Lines& d = *s.lines_buf;
  m.wait(d);
  m.check_guards(d);
  const LineExtents e = LineExtents::of(m.tables, s.lines);
  const auto to = s.readback.prepare(e, out);
  d.outputs(e, [&](Arr& a, size_t bytes, size_t k) { std::memcpy(to[k], a.ptr(), bytes); });
  s.readback.finish(out);
  times_ = m.times(d);
  s.busy = s.submitted = false;
}

// Single stages: inputs written, one stage recorded between its copies, run, waited for.

void VulkanBackend::stripes(const uint8_t* frames, int count, const int* frame_slot,
                            StripeOutput& out) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  Impl::Lines& d = m.lines_bufs[2];
  m.ensure(d, (count + 1) / 2);
  const size_t cols = size_t(count) * m.tables.width;
  std::memcpy(d.frames.ptr(), frames, cols * m.tables.height);
  std::memcpy(d.frame_slot.ptr(), frame_slot, size_t(count) * 4);
  m.begin(d);
  m.stamp(d, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  m.copy_in(d, {{&d.frames, cols * m.tables.height}, {&d.frame_slot, VkDeviceSize(count) * 4}});
  m.stamp(d, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
  m.record_stripes(d, count);
  m.stamp(d, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  m.copy_out(d, {{&d.row, cols * 4},
                 {&d.peak, cols * 4},
                 {&d.width, cols * 4},
                 {&d.asym, cols * 4},
                 {&d.centroid, cols * 4},
                 {&d.valid, cols * 4}});
  m.stamp(d, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  m.end_and_submit(d);
  m.wait(d);
  m.check_guards(d);
  out.resize(cols);
  std::memcpy(out.row.data(), d.row.ptr(), cols * 4);
  std::memcpy(out.peak.data(), d.peak.ptr(), cols * 4);
  std::memcpy(out.width.data(), d.width.ptr(), cols * 4);
  std::memcpy(out.asym.data(), d.asym.ptr(), cols * 4);
  std::memcpy(out.centroid.data(), d.centroid.ptr(), cols * 4);
  to_flags(d.valid.ptr(), cols, out.valid.data());
  times_ = m.times(d);
}

void VulkanBackend::rectify(const float* row, const uint8_t* valid, int count,
                            const int* frame_slot, float* x, float* z, uint8_t* out_valid) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  Impl::Lines& d = m.lines_bufs[2];
  m.ensure(d, (count + 1) / 2);
  const size_t cols = size_t(count) * m.tables.width;
  std::memcpy(d.row.ptr(), row, cols * 4);
  from_flags(valid, cols, d.valid.ptr());
  std::memcpy(d.frame_slot.ptr(), frame_slot, size_t(count) * 4);
  m.begin(d);
  m.stamp(d, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  m.copy_in(d,
            {{&d.row, cols * 4}, {&d.valid, cols * 4}, {&d.frame_slot, VkDeviceSize(count) * 4}});
  m.stamp(d, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
  m.record_rectify(d, count);
  m.stamp(d, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  m.copy_out(d, {{&d.x, cols * 4}, {&d.z, cols * 4}, {&d.xz_valid, cols * 4}});
  m.stamp(d, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  m.end_and_submit(d);
  m.wait(d);
  m.check_guards(d);
  std::memcpy(x, d.x.ptr(), cols * 4);
  std::memcpy(z, d.z.ptr(), cols * 4);
  to_flags(d.xz_valid.ptr(), cols, out_valid);
  times_ = m.times(d);
}

void VulkanBackend::fuse(const float* x, const float* z, const uint8_t* valid, int lines,
                         const int* lane_slot, float* profile, uint8_t* profile_valid,
                         FusionStats* stats) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  Impl::Lines& d = m.lines_bufs[2];
  m.ensure(d, lines);
  const size_t cols = size_t(lines) * 2 * m.tables.width, G = size_t(m.tables.grid_n);
  std::memcpy(d.x.ptr(), x, cols * 4);
  std::memcpy(d.z.ptr(), z, cols * 4);
  from_flags(valid, cols, d.xz_valid.ptr());
  std::memcpy(d.lane_slot.ptr(), lane_slot, size_t(lines) * 4);
  m.begin(d);
  m.stamp(d, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  m.copy_in(d, {{&d.x, cols * 4},
                {&d.z, cols * 4},
                {&d.xz_valid, cols * 4},
                {&d.lane_slot, VkDeviceSize(lines) * 4}});
  m.stamp(d, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
  m.record_fuse(d, lines);
  m.stamp(d, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  m.copy_out(d, {{&d.profile, VkDeviceSize(lines) * G * 4},
                 {&d.profile_valid, VkDeviceSize(lines) * G * 4},
                 {&d.counts, VkDeviceSize(lines) * sizeof(kernel::FusionCountK)}});
  m.stamp(d, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  m.end_and_submit(d);
  m.wait(d);
  m.check_guards(d);
  std::memcpy(profile, d.profile.ptr(), size_t(lines) * G * 4);
  to_flags(d.profile_valid.ptr(), size_t(lines) * G, profile_valid);
  if (stats)
    add_fusion_counts(reinterpret_cast<const kernel::FusionCountK*>(d.counts.ptr()), size_t(lines),
                      *stats);
  times_ = m.times(d);
}

void VulkanBackend::project(const float* profile, const uint8_t* profile_valid, int lines,
                            const int* lane_slot, float* thickness, uint8_t* thickness_valid) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  Impl::Lines& d = m.lines_bufs[2];
  m.ensure(d, lines);
  const size_t G = size_t(m.tables.grid_n), P = size_t(m.tables.pixels);
  std::memcpy(d.profile.ptr(), profile, size_t(lines) * G * 4);
  from_flags(profile_valid, size_t(lines) * G, d.profile_valid.ptr());
  std::memcpy(d.lane_slot.ptr(), lane_slot, size_t(lines) * 4);
  // The highest valid sample of each line, as the fusion shader leaves it for the projection.
  float* top = reinterpret_cast<float*>(d.top.ptr());
  for (int l = 0; l < lines; ++l) {
    top[l] = 0.f;
    for (size_t g = 0; g < G; ++g)
      if (profile_valid[size_t(l) * G + g]) top[l] = std::max(top[l], profile[size_t(l) * G + g]);
  }
  m.begin(d);
  m.stamp(d, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
  m.copy_in(d, {{&d.profile, VkDeviceSize(lines) * G * 4},
                {&d.profile_valid, VkDeviceSize(lines) * G * 4},
                {&d.top, VkDeviceSize(lines) * 4},
                {&d.lane_slot, VkDeviceSize(lines) * 4}});
  m.stamp(d, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
  m.record_project(d, lines);
  m.stamp(d, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  m.copy_out(d, {{&d.thickness, VkDeviceSize(lines) * P * 4},
                 {&d.thickness_valid, VkDeviceSize(lines) * P * 4}});
  m.stamp(d, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  m.end_and_submit(d);
  m.wait(d);
  m.check_guards(d);
  std::memcpy(thickness, d.thickness.ptr(), size_t(lines) * P * 4);
  to_flags(d.thickness_valid.ptr(), size_t(lines) * P, thickness_valid);
  times_ = m.times(d);
}

}  // namespace rangex

namespace rangex {

double VulkanBackend::upload_bandwidth(size_t bytes) {
  Impl& m = *impl_;
  if (m.dev->unified()) return 0;  // the shaders read host-visible memory in place
  vk::Buffer host = m.dev->buffer(bytes, true);
  vk::Buffer dev = m.dev->buffer(bytes, false);
  std::memset(host.data(), 1, bytes);
  double best = 0;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    m.once([&](VkCommandBuffer cb) {
      VkBufferCopy r{host.offset, dev.offset, bytes};
      vkCmdCopyBuffer(cb, host.buf, dev.buf, 1, &r);
    });
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s > 0) best = std::max(best, double(bytes) / s);
  }
  m.dev->destroy(host);
  m.dev->destroy(dev);
  return best;
}

}  // namespace rangex

namespace rangex {

void VulkanBackend::pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                                float* z) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  Impl::Lines& s = m.begin_fillets(b);
  Impl::Fillets& d = m.fb;
  m.dispatch_fillets(s, kPseudo, b.fillets);
  const VkDeviceSize n = VkDeviceSize(b.pixels());
  m.copy_out(s, {{&d.ln_p, n * 4}, {&d.p, n * 4}, {&d.residual, n * 4}, {&d.z, n * 4}});
  m.finish_fillets(s);
  std::memcpy(ln_p, d.ln_p.ptr(), n * 4);
  std::memcpy(p, d.p.ptr(), n * 4);
  std::memcpy(residual, d.residual.ptr(), n * 4);
  std::memcpy(z, d.z.ptr(), n * 4);
  times_ = m.times(s);
}

void VulkanBackend::irls_sums(const FilletBatch& b, double* r, double* sums) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  Impl::Lines& s = m.begin_fillets(b);
  Impl::Fillets& d = m.fb;
  m.dispatch_fillets(s, kIrls, b.fillets);
  const VkDeviceSize n = VkDeviceSize(b.pixels()), k = VkDeviceSize(b.fillets) * IRLS_SUMS * 8;
  m.copy_out(s, {{&d.r, n * 8}, {&d.sums, k}});
  m.finish_fillets(s);
  std::memcpy(r, d.r.ptr(), n * 8);
  std::memcpy(sums, d.sums.ptr(), k);
  times_ = m.times(s);
}

void VulkanBackend::dual_energy(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis,
                                float* lengths, float* sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  Impl::Pixels& d = m.begin_pixels(b.pixels, k);
  const size_t n = size_t(b.pixels);
  std::memcpy(d.low.ptr(), b.low, n * 2);
  std::memcpy(d.high.ptr(), b.high, n * 2);
  std::memcpy(d.open_low.ptr(), b.open_low, n * 4);
  std::memcpy(d.open_high.ptr(), b.open_high, n * 4);
  std::memcpy(d.thickness.ptr(), b.thickness, n * 4);
  if (b.use)
    std::memcpy(d.use.ptr(), b.use, n);
  else
    std::memset(d.use.ptr(), 1, n);
  const VkDeviceSize w16 = VkDeviceSize((n * 2 + 3) / 4 * 4), w8 = VkDeviceSize((n + 3) / 4 * 4);
  m.run_pixels(kDualEnergy, {b.pixels, 0, 0.0},
               {{&d.low, w16},
                {&d.high, w16},
                {&d.open_low, n * 4},
                {&d.open_high, n * 4},
                {&d.thickness, n * 4},
                {&d.use, w8},
                {&d.params, sizeof k}},
               {{&d.basis, n * 20}, {&d.lengths, n * 12}, {&d.sigma, n * 12}});
  std::memcpy(basis, d.basis.ptr(), n * 20);
  std::memcpy(lengths, d.lengths.ptr(), n * 12);
  std::memcpy(sigma, d.sigma.ptr(), n * 12);
  times_ = m.times(m.lines_bufs[2]);
}

void VulkanBackend::dual_energy_bone(const DualEnergyBoneBatch& b, const DualEnergyParams& k,
                                     float* bone, float* bone_sigma) {
  check_dual_energy_batch(b, k);
  if (b.pixels == 0) return;
  Impl& m = *impl_;
  Impl::Pixels& d = m.begin_pixels(b.pixels, k);
  const size_t n = size_t(b.pixels);
  std::memcpy(d.basis.ptr(), b.basis, n * 20);
  std::memcpy(d.thickness.ptr(), b.thickness, n * 4);
  std::memcpy(d.phi.ptr(), b.phi, n * 4);
  std::memcpy(d.phi_var.ptr(), b.phi_var, n * 4);
  m.run_pixels(kDualEnergyBone, {b.pixels, 0, b.density_var},
               {{&d.basis, n * 20},
                {&d.thickness, n * 4},
                {&d.phi, n * 4},
                {&d.phi_var, n * 4},
                {&d.params, sizeof k}},
               {{&d.bone, n * 4}, {&d.bone_sigma, n * 4}});
  std::memcpy(bone, d.bone.ptr(), n * 4);
  std::memcpy(bone_sigma, d.bone_sigma.ptr(), n * 4);
  times_ = m.times(m.lines_bufs[2]);
}

}  // namespace rangex
