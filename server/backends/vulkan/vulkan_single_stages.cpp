// The vulkan backend's single stages (the stage tests and benchmarks): inputs written, one
// stage recorded between its copies, run, waited for.
#include <algorithm>
#include <chrono>
#include <cstring>

#include "backends/vulkan/vulkan_backend.h"
#include "backends/vulkan/vulkan_backend_impl.h"
#include "core/error.h"

namespace rangex {

namespace {

// The shaders' flags are 32-bit (a bool array in std430); the host's are bytes.
void to_flags(const uint8_t* in, size_t n, uint8_t* out) {
  const int32_t* v = reinterpret_cast<const int32_t*>(in);
  for (size_t i = 0; i < n; ++i) out[i] = uint8_t(v[i] != 0);
}
void from_flags(const uint8_t* in, size_t n, uint8_t* out) {
  int32_t* v = reinterpret_cast<int32_t*>(out);
  for (size_t i = 0; i < n; ++i) v[i] = in[i];
}

}  // namespace

void VulkanBackend::stripes(const uint8_t* frames, int count, const int* frame_slot,
                            StripeOutput& out) {
  Impl& m = *impl_;
  if (lanes_.empty()) fail("backend vulkan: no lanes set");
  Impl::Lines& d = m.lines_bufs[2];
  m.ensure(d, (count + 1) / 2);
  const size_t cols = size_t(count) * m.tables.width;
  std::memcpy(d.frames.ptr(), frames, cols * m.tables.height);
  std::memcpy(d.frame_slot.ptr(), frame_slot, size_t(count) * 4);
  m.run_scratch({{&d.frames, cols * m.tables.height}, {&d.frame_slot, VkDeviceSize(count) * 4}},
                [&](Impl::Lines& s) { m.record_stripes(s, count); },
                {{&d.row, cols * 4},
                 {&d.peak, cols * 4},
                 {&d.width, cols * 4},
                 {&d.asym, cols * 4},
                 {&d.centroid, cols * 4},
                 {&d.valid, cols * 4}});
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
  m.run_scratch(
      {{&d.row, cols * 4}, {&d.valid, cols * 4}, {&d.frame_slot, VkDeviceSize(count) * 4}},
      [&](Impl::Lines& s) { m.record_rectify(s, count); },
      {{&d.x, cols * 4}, {&d.z, cols * 4}, {&d.xz_valid, cols * 4}});
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
  m.run_scratch({{&d.x, cols * 4},
                 {&d.z, cols * 4},
                 {&d.xz_valid, cols * 4},
                 {&d.lane_slot, VkDeviceSize(lines) * 4}},
                [&](Impl::Lines& s) { m.record_fuse(s, lines); },
                {{&d.profile, VkDeviceSize(lines) * G * 4},
                 {&d.profile_valid, VkDeviceSize(lines) * G * 4},
                 {&d.counts, VkDeviceSize(lines) * sizeof(kernel::FusionCountK)}});
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
  m.run_scratch({{&d.profile, VkDeviceSize(lines) * G * 4},
                 {&d.profile_valid, VkDeviceSize(lines) * G * 4},
                 {&d.top, VkDeviceSize(lines) * 4},
                 {&d.lane_slot, VkDeviceSize(lines) * 4}},
                [&](Impl::Lines& s) { m.record_project(s, lines); },
                {{&d.thickness, VkDeviceSize(lines) * P * 4},
                 {&d.thickness_valid, VkDeviceSize(lines) * P * 4}});
  m.check_guards(d);
  std::memcpy(thickness, d.thickness.ptr(), size_t(lines) * P * 4);
  to_flags(d.thickness_valid.ptr(), size_t(lines) * P, thickness_valid);
  times_ = m.times(d);
}

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
