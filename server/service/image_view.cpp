#include "service/image_view.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/error.h"
#include "core/png_io.h"

namespace rangex {

namespace {
// The value below which `q` of `v` lies (v is reordered).
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + long(k), v.end());
  return v[k];
}
uint8_t to8(double x) {
  return uint8_t(std::clamp(std::lround(x), 0L, 255L));
}
}  // namespace

std::string display_png(const std::string& path, const std::string& kind) {
  int w = 0, h = 0;
  const std::vector<uint16_t> px = read_png16(path, w, h);
  std::vector<uint8_t> out(px.size(), 0);
  std::vector<double> vals;
  vals.reserve(px.size());
  if (kind == "xray" || kind == "xray_high" || kind == "pseudo_xray" || kind == "thickness") {
    // 0 (pseudo-X-ray: not modelled) and 65535 (thickness: not measured) carry no value.
    for (uint16_t v : px)
      if (v != 0 && v != 65535) vals.push_back(v);
    const double lo = kind == "thickness" ? 0.0 : quantile(vals, 0.005);
    const double hi = std::max(lo + 1, quantile(vals, 0.995));
    for (size_t i = 0; i < px.size(); ++i)
      if (px[i] != 0 && px[i] != 65535) out[i] = to8(255.0 * (px[i] - lo) / (hi - lo));
  } else if (kind == "residual") {
    // Grey at zero; darker where the X-ray saw more than the meat explains (bone), brighter
    // where less (air), over six robust deviations.
    for (uint16_t v : px)
      if (v != 32768) vals.push_back(std::fabs(double(v) - 32768.0));
    const double spread = std::max(1.0, 1.4826 * quantile(vals, 0.5));
    for (size_t i = 0; i < px.size(); ++i)
      out[i] = to8(128.0 + 127.0 * (double(px[i]) - 32768.0) / (6 * spread));
  } else if (kind == "bone") {
    // Dual energy: grey at no bone, darker with more (as the residual), over 1 mm.
    for (size_t i = 0; i < px.size(); ++i)
      out[i] = to8(128.0 - 127.0 * (double(px[i]) - 32768.0) / 1000.0);
  } else if (kind == "fat_share") {
    // 0 .. 50 % fat of the soft tissue as black .. white.
    for (size_t i = 0; i < px.size(); ++i) out[i] = to8(255.0 * px[i] / 32768.0);
  } else {
    fail("no view of image kind '", kind,
         "' (xray, xray_high, thickness, pseudo_xray, residual, bone, fat_share)");
  }
  return encode_png8(out.data(), w, h);
}

}  // namespace rangex
