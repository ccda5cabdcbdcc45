#include "backends/vulkan/vulkan_backend.h"

#include <string>

#include "backends/vulkan/vulkan_backend_impl.h"
#include "core/error.h"
#include "shaders_spv.h"

namespace rangex {

std::vector<VulkanDevice> vulkan_devices() {
  // No loader or driver throws, naming what failed: a probe tells that from a device that
  // lacks a feature.
  std::vector<VulkanDevice> out;
  vk::Instance inst;
  for (const auto& d : inst.devices()) out.push_back({d.name, d.cpu});
  return out;
}

VulkanBackend::VulkanBackend(const VulkanOptions& opt) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.opt = opt;
  m.inst = std::make_unique<vk::Instance>();
  const vk::DeviceChoice d = m.inst->choose(opt.device);
  m.dev = std::make_unique<vk::Device>(*m.inst, d);
  VkDevice dv = m.dev->get();
  m.k[Impl::kStripe] = vk::make_kernel(*m.dev, shaders::kStripe, sizeof shaders::kStripe, 10,
                                       sizeof(kernel::StripePush));
  m.k[Impl::kRectify] = vk::make_kernel(*m.dev, shaders::kRectify, sizeof shaders::kRectify, 8,
                                        sizeof(kernel::RectifyPush));
  m.k[Impl::kResample] = vk::make_kernel(
      *m.dev, shaders::kFuseResample, sizeof shaders::kFuseResample, 6, sizeof(kernel::FusePush));
  m.k[Impl::kMerge] = vk::make_kernel(*m.dev, shaders::kFuseMerge, sizeof shaders::kFuseMerge, 7,
                                      sizeof(kernel::FusePush));
  m.k[Impl::kProject] = vk::make_kernel(*m.dev, shaders::kProject, sizeof shaders::kProject, 7,
                                        sizeof(kernel::ProjectPush));
  m.k[Impl::kPseudo] = vk::make_kernel(*m.dev, shaders::kPseudoXray, sizeof shaders::kPseudoXray,
                                       10, sizeof(kernel::FilletPush));
  m.k[Impl::kIrls] = vk::make_kernel(*m.dev, shaders::kIrlsSums, sizeof shaders::kIrlsSums, 8,
                                     sizeof(kernel::FilletPush));
  m.k[Impl::kDualEnergy] =
      vk::make_kernel(*m.dev, shaders::kDualEnergy, sizeof shaders::kDualEnergy, 10,
                      sizeof(kernel::DualEnergyPush));
  m.k[Impl::kDualEnergyBone] =
      vk::make_kernel(*m.dev, shaders::kDualEnergyBone, sizeof shaders::kDualEnergyBone, 7,
                      sizeof(kernel::DualEnergyPush));
  m.dev->save_cache();
  // Descriptor sets for the three buffer groups, allocated once and updated when buffers
  // or tables change (never while a batch that uses them is in flight).
  VkDescriptorPoolSize ps{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                          3 * (10 + 8 + 6 + 7 + 7 + 10 + 8 + 10 + 7)};
  VkDescriptorPoolCreateInfo pi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pi.maxSets = 3 * Impl::kKernels;
  pi.poolSizeCount = 1;
  pi.pPoolSizes = &ps;
  vk::check(vkCreateDescriptorPool(dv, &pi, nullptr, &m.pool), "vkCreateDescriptorPool");
  VkCommandPoolCreateInfo cpi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  cpi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  cpi.queueFamilyIndex = m.dev->family();
  vk::check(vkCreateCommandPool(dv, &cpi, nullptr, &m.cmd_pool), "vkCreateCommandPool");
  uint32_t nq = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(d.physical, &nq, nullptr);
  std::vector<VkQueueFamilyProperties> qs(nq);
  vkGetPhysicalDeviceQueueFamilyProperties(d.physical, &nq, qs.data());
  if (qs[m.dev->family()].timestampValidBits > 0 && d.props.limits.timestampPeriod > 0) {
    VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qi.queryCount = 12;
    vk::check(vkCreateQueryPool(dv, &qi, nullptr, &m.queries), "vkCreateQueryPool");
    m.tick_ns = d.props.limits.timestampPeriod;
  }
  for (int i = 0; i < 3; ++i) {
    Impl::Lines& L = m.lines_bufs[i];
    L.index = i;
    for (int kk = 0; kk < Impl::kKernels; ++kk) {
      VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
      ai.descriptorPool = m.pool;
      ai.descriptorSetCount = 1;
      ai.pSetLayouts = &m.k[kk].set_layout;
      vk::check(vkAllocateDescriptorSets(dv, &ai, &L.sets[kk]), "vkAllocateDescriptorSets");
    }
    VkCommandBufferAllocateInfo ci{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ci.commandPool = m.cmd_pool;
    ci.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ci.commandBufferCount = 1;
    vk::check(vkAllocateCommandBuffers(dv, &ci, &L.cb), "vkAllocateCommandBuffers");
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    vk::check(vkCreateFence(dv, &fi, nullptr, &L.fence), "vkCreateFence");
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
    for (Impl::Arr* a : L.all()) m.free(*a);
    if (L.fence) vkDestroyFence(dv, L.fence, nullptr);
  }
  for (vk::Buffer* b : {&m.t_stripe, &m.t_rect, &m.t_nodes, &m.t_geom, &m.t_ln, &m.t_ln_dn})
    m.dev->destroy(*b);
  for (Impl::Arr* a : m.fb.all()) m.free(*a);
  for (Impl::Arr* a : m.px.all()) m.free(*a);
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
    for (Impl::Arr* a : L.all()) m.free(*a);
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
  Impl::Copies outs;
  d.outputs(LineExtents::of(m.tables, lines), [&](Impl::Arr& a, size_t bytes, size_t) {
    outs.emplace_back(&a, VkDeviceSize(bytes));
  });
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
  d.outputs(e, [&](Impl::Arr& a, size_t bytes, size_t k) { std::memcpy(to[k], a.ptr(), bytes); });
  s.readback.finish(out);
  times_ = m.times(d);
  s.busy = s.submitted = false;
}

}  // namespace rangex
