// The vulkan backend's fillet stages (pseudo-X-ray map, IRLS sums) and dual-energy stages:
// their buffers, grown as needed, run on the scratch command buffer.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "backends/vulkan/vulkan_backend.h"
#include "backends/vulkan/vulkan_backend_impl.h"

namespace rangex {

// The fillet stages.

void VulkanBackend::Impl::ensure(Fillets& d, const FilletBatch& b) {
  const size_t n = std::max<size_t>(size_t(b.pixels()), 4);
  bool changed = false;
  if (n > d.pixels) {
    for (Arr* a : {&d.thickness, &d.xray, &d.use, &d.ln_p, &d.p, &d.residual, &d.z, &d.r}) free(*a);
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

// Writes a batch of fillets' inputs into the arrays (their host side); returns the copies
// to the device that a stage over them needs.
VulkanBackend::Impl::Copies VulkanBackend::Impl::write_fillets(const FilletBatch& b) {
  check_fillet_batch(b);
  Fillets& d = fb;
  ensure(d, b);
  const size_t n = size_t(b.pixels());
  std::memcpy(d.thickness.ptr(), b.thickness, n * 4);
  std::memcpy(d.xray.ptr(), b.xray, n * 2);
  std::memcpy(d.use.ptr(), b.use, n);
  std::memcpy(d.offsets.ptr(), b.offsets, size_t(b.fillets + 1) * 4);
  std::memcpy(d.models.ptr(), b.models, size_t(b.fillets) * sizeof(kernel::FilletModelK));
  return {{&d.thickness, VkDeviceSize(n * 4)},
          {&d.xray, VkDeviceSize((n * 2 + 3) / 4 * 4)},
          {&d.use, VkDeviceSize((n + 3) / 4 * 4)},
          {&d.offsets, VkDeviceSize(b.fillets + 1) * 4},
          {&d.models, VkDeviceSize(b.fillets) * sizeof(kernel::FilletModelK)}};
}

// One work-group per fillet (the IRLS sums reduce over it).
void VulkanBackend::Impl::dispatch_fillets(Lines& s, K which, int fillets) {
  const vk::Kernel& kk = k[which];
  const kernel::FilletPush push{fillets, 0, 0, 0};
  vkCmdBindPipeline(s.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.pipeline);
  vkCmdBindDescriptorSets(s.cb, VK_PIPELINE_BIND_POINT_COMPUTE, kk.layout, 0, 1, &s.sets[which], 0,
                          nullptr);
  vkCmdPushConstants(s.cb, kk.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, kk.push_bytes, &push);
  vkCmdDispatch(s.cb, uint32_t(fillets), 1, 1);
}

void VulkanBackend::Impl::check_fillet_guards() {
  if (opt.guards)
    for (Arr* a : fb.all()) dev->check_guards(a->dev, "fillets");
}

void VulkanBackend::pseudo_xray(const FilletBatch& b, float* ln_p, float* p, float* residual,
                                float* z) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  Impl::Fillets& d = m.fb;
  const VkDeviceSize n = VkDeviceSize(b.pixels());
  m.run_scratch(m.write_fillets(b),
                [&](Impl::Lines& s) { m.dispatch_fillets(s, Impl::kPseudo, b.fillets); },
                {{&d.ln_p, n * 4}, {&d.p, n * 4}, {&d.residual, n * 4}, {&d.z, n * 4}});
  m.check_fillet_guards();
  std::memcpy(ln_p, d.ln_p.ptr(), n * 4);
  std::memcpy(p, d.p.ptr(), n * 4);
  std::memcpy(residual, d.residual.ptr(), n * 4);
  std::memcpy(z, d.z.ptr(), n * 4);
  times_ = m.times(m.lines_bufs[2]);
}

void VulkanBackend::irls_sums(const FilletBatch& b, double* r, double* sums) {
  Impl& m = *impl_;
  if (b.fillets == 0) return;
  Impl::Fillets& d = m.fb;
  const VkDeviceSize n = VkDeviceSize(b.pixels()), k = VkDeviceSize(b.fillets) * IRLS_SUMS * 8;
  m.run_scratch(m.write_fillets(b),
                [&](Impl::Lines& s) { m.dispatch_fillets(s, Impl::kIrls, b.fillets); },
                {{&d.r, n * 8}, {&d.sums, k}});
  m.check_fillet_guards();
  std::memcpy(r, d.r.ptr(), n * 8);
  std::memcpy(sums, d.sums.ptr(), k);
  times_ = m.times(m.lines_bufs[2]);
}

// The dual-energy stages.

static_assert(sizeof(kernel::DualEnergyK) == 512, "the std430 layout of shared/dual_energy.h");

void VulkanBackend::Impl::ensure(Pixels& d, size_t pixels) {
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
VulkanBackend::Impl::Pixels& VulkanBackend::Impl::begin_pixels(int pixels,
                                                               const DualEnergyParams& k) {
  ensure(px, size_t(pixels));
  std::memcpy(px.params.ptr(), &k, sizeof k);
  return px;
}

// Runs one dual-energy stage on the scratch command buffer (one invocation a pixel).
void VulkanBackend::Impl::run_pixels(K which, const kernel::DualEnergyPush& push, const Copies& ins,
                                     const Copies& outs) {
  run_scratch(
      ins, [&](Lines& s) { dispatch(s, which, &push, uint32_t(push.pixels)); }, outs);
  if (opt.guards)
    for (Arr* a : px.all()) dev->check_guards(a->dev, "dual energy");
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
  m.run_pixels(Impl::kDualEnergy, {b.pixels, 0, 0.0},
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
  m.run_pixels(Impl::kDualEnergyBone, {b.pixels, 0, b.density_var},
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
