// What the vulkan backend holds on its device, and how it records a command buffer: the
// buffer groups (a batch of lines, a batch of fillets, a batch of dual-energy pixels) with
// their descriptor sets, command buffers and fences; copies, dispatches, barriers and
// timestamps. Shared by the backend's sources: vulkan_backend.cpp (the device and the line
// batches), vulkan_single_stages.cpp and vulkan_fillet_stages.cpp.
#pragma once
#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <utility>
#include <vector>

#include "backends/device_lines.h"
#include "backends/lane_tables.h"
#include "backends/vulkan/vk_runtime.h"
#include "backends/vulkan/vulkan_backend.h"
#include "shared/push_constants.h"

namespace rangex {

struct VulkanBackend::Impl {
  // The shaders, in the order of their descriptor sets.
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

  // An array the shaders use: on the device, and (when the device's memory is not mappable)
  // a host mirror that inputs are written to and results read from, copied in the command
  // buffer.
  struct Arr {
    vk::Buffer dev, host;
    bool mirrored = false;
    uint8_t* ptr() const { return mirrored ? host.data() : dev.data(); }
  };
  // Arrays to copy between host mirror and device, with the bytes of each.
  using Copies = std::vector<std::pair<Arr*, VkDeviceSize>>;

  static void barrier(VkCommandBuffer cb, VkPipelineStageFlags src, VkAccessFlags src_access,
                      VkPipelineStageFlags dst, VkAccessFlags dst_access) {
    VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    mb.srcAccessMask = src_access;
    mb.dstAccessMask = dst_access;
    vkCmdPipelineBarrier(cb, src, dst, 0, 1, &mb, 0, nullptr, 0, nullptr);
  }

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
  std::array<Slot, 2> slots;
  int next = 0;

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

  // The fillet and dual-energy batches (vulkan_fillet_stages.cpp).
  void ensure(Fillets& d, const FilletBatch& b);
  Copies write_fillets(const FilletBatch& b);
  void dispatch_fillets(Lines& s, K which, int fillets);
  void check_fillet_guards();
  void ensure(Pixels& d, size_t pixels);
  Pixels& begin_pixels(int pixels, const DualEnergyParams& k);
  void run_pixels(K which, const kernel::DualEnergyPush& push, const Copies& ins,
                  const Copies& outs);

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

  // Runs one stage on the scratch command buffer and waits: `ins` copied in, the commands
  // `record` writes, `outs` copied out, with the four timestamps between them.
  template <typename F>
  void run_scratch(const Copies& ins, F&& record, const Copies& outs) {
    Lines& s = lines_bufs[2];
    begin(s);
    stamp(s, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    copy_in(s, ins);
    stamp(s, 1, VK_PIPELINE_STAGE_TRANSFER_BIT);
    record(s);
    stamp(s, 2, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    copy_out(s, outs);
    stamp(s, 3, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
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
    vk::check(vkResetCommandBuffer(d.cb, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    vk::check(vkBeginCommandBuffer(d.cb, &bi), "vkBeginCommandBuffer");
    if (tick_ns) vkCmdResetQueryPool(d.cb, queries, uint32_t(4 * d.index), 4);
  }
  void stamp(Lines& d, int i, VkPipelineStageFlagBits stage) {
    if (tick_ns) vkCmdWriteTimestamp(d.cb, stage, queries, uint32_t(4 * d.index + i));
  }
  void end_and_submit(Lines& d) {
    vk::check(vkEndCommandBuffer(d.cb), "vkEndCommandBuffer");
    vk::check(vkResetFences(dev->get(), 1, &d.fence), "vkResetFences");
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &d.cb;
    vk::check(vkQueueSubmit(dev->queue(), 1, &si, d.fence), "vkQueueSubmit");
  }
  void wait(Lines& d) {
    vk::check(vkWaitForFences(dev->get(), 1, &d.fence, VK_TRUE, uint64_t(60) * 1000000000ull),
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
  void copy_in(Lines& d, const Copies& ins) {
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
  void copy_out(Lines& d, const Copies& outs) {
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

}  // namespace rangex
