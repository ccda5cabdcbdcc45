// A stored fillet image made viewable in a browser: the 16-bit records (X-ray counts,
// thickness in 0.01 mm, pseudo-X-ray, residual about 32768) stretched to 8 bits over their
// own range, so that a fillet fills the grey scale whatever the beam. The records on disk
// are never changed; the overlay is already 8-bit and is served as it is.
#pragma once
#include <string>

namespace rangex {

// kind: xray | thickness | pseudo_xray | residual. Throws Error for another kind or a file
// that is not a 16-bit grayscale PNG.
std::string display_png(const std::string& path, const std::string& kind);

}  // namespace rangex
