#include "backends/device_lines.h"

namespace rangex {

namespace {
void to_flags(const std::vector<int32_t>& in, uint8_t* out) {
  for (size_t i = 0; i < in.size(); ++i) out[i] = in[i] != 0;
}
}  // namespace

LineExtents LineExtents::of(const KernelTables& t, int lines) {
  const size_t n = size_t(lines);
  return {n, n * 2 * size_t(t.width), size_t(t.height), size_t(t.grid_n), size_t(t.pixels)};
}

std::array<void*, LineReadback::kOutputs> LineReadback::prepare(const LineExtents& e,
                                                                LineResults& out) {
  e_ = e;
  out.stripes.resize(e.cols);
  out.x.resize(e.cols);
  out.z.resize(e.cols);
  out.xz_valid.resize(e.cols);
  out.profile.resize(e.lines * e.G);
  out.profile_valid.resize(e.lines * e.G);
  out.thickness.resize(e.lines * e.P);
  out.thickness_valid.resize(e.lines * e.P);
  valid_.resize(e.cols);
  xz_valid_.resize(e.cols);
  profile_valid_.resize(e.lines * e.G);
  thickness_valid_.resize(e.lines * e.P);
  counts_.resize(e.lines);
  return {out.stripes.row.data(),
          out.stripes.peak.data(),
          out.stripes.width.data(),
          out.stripes.asym.data(),
          out.stripes.centroid.data(),
          valid_.data(),
          out.x.data(),
          out.z.data(),
          xz_valid_.data(),
          out.profile.data(),
          profile_valid_.data(),
          counts_.data(),
          out.thickness.data(),
          thickness_valid_.data()};
}

void LineReadback::finish(LineResults& out) {
  to_flags(valid_, out.stripes.valid.data());
  to_flags(xz_valid_, out.xz_valid.data());
  to_flags(profile_valid_, out.profile_valid.data());
  to_flags(thickness_valid_, out.thickness_valid.data());
  add_fusion_counts(counts_.data(), counts_.size(), out.fusion);
}

void add_fusion_counts(const kernel::FusionCountK* counts, size_t lines, FusionStats& stats) {
  for (size_t l = 0; l < lines; ++l) {
    const kernel::FusionCountK& c = counts[l];
    stats += {c.both, c.single_cam, c.conflict, c.filled, c.missing};
  }
}

}  // namespace rangex
