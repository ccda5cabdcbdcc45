// A stored fillet image made viewable in a browser: the 16-bit records (X-ray counts,
// thickness in 0.01 mm, pseudo-X-ray, residual about 32768) stretched to 8 bits over their
// own range, so that a fillet fills the grey scale whatever the beam. The records on disk
// are never changed; the overlay is already 8-bit and is served as it is.
#pragma once
#include <string>

namespace rangex {

// Every kind of image a fillet's record may hold, in the order a viewer shows them (the
// dual-energy kinds only for a lane of two energies).
inline constexpr const char* kImageKinds[] = {"overlay",     "xray",     "xray_high", "thickness",
                                              "pseudo_xray", "residual", "bone",      "fat_share"};
inline bool is_image_kind(const std::string& kind) {
  for (const char* k : kImageKinds)
    if (kind == k) return true;
  return false;
}

// kind: one of kImageKinds but the overlay. Throws Error for another kind or a file that is
// not a 16-bit grayscale PNG.
std::string display_png(const std::string& path, const std::string& kind);

}  // namespace rangex
