// Round kernels whitened by the product's own texture. A fragment's excess attenuation is a
// known shape s (a calcified sphere's chord); what compensation leaves around it is not
// white (meat texture and marbling correlated over millimetres, thickness error). In such
// noise the linear detector with the best signal-to-noise ratio is the whitened matched
// filter h = C^-1 s, C the noise's covariance over the kernel's window: it learns from the
// plant's clean fillets which scales the texture fills and looks for bone where it does not.
// One kernel is matched to one size and takes larger pieces for texture, so a bank of sizes
// is learned and a pixel is as bone-like as its most bone-like kernel (as the needle
// directions). The CPU reference over flat row-major buffers, like masked_smooth.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/learned_detection.h"

namespace rangex {

// z with its values above median + clip x spread (robust, over `use`) set to that bound, on
// the usable pixels (NaN elsewhere): a bright speck cannot push a kernel's flank to bone.
// With reach > 0, each pixel first less how far the bright level enclosing it within reach
// px stands above that bound (pipeline/bright_enclosure.h): a dip inside a fat streak keeps
// its depth below the streak instead of being cut to the streak's clipped value.
// With void_level > 0, the pixels above median + void_level x spread and their 8 neighbours
// are a void (an air pocket, no texture of the meat): set to the median, as flat meat.
void clip_bright(const float* z, const uint8_t* use, int rows, int cols, double clip, int reach,
                 double void_level, std::vector<float>& out);

// The q-quantile of z over the usable finite pixels in robust spreads above their median
// (NaN when there are none or no spread): how bright a fillet's brightest texture stands.
double bright_quantile(const float* z, const uint8_t* use, size_t n, double q);

// A product's void level: `factor` times the median of its learning fillets' bright
// quantiles (bright_quantile at 0.999), never below `clip`; 0 when factor is 0 or there are
// none.
double learned_void_level(std::vector<double> bright_quantiles, double factor, double clip);

// The autocovariance of z across fillets, at lags up to max_lag pixels in rows and columns.
// Each fillet's z is brought to unit robust spread and clipped as detection clips it (with
// the bright enclosure of `reach` px when reach > 0, voids flattened above void_level > 0);
// a lag is averaged over the pixel pairs both usable.
class TextureCovariance {
 public:
  explicit TextureCovariance(int max_lag, double clip = 3, int reach = 0, double void_level = 0);
  void add(const float* z, const uint8_t* use, int rows, int cols);
  int max_lag() const { return max_lag_; }
  double clip() const { return clip_; }
  int reach() const { return reach_; }
  double void_level() const { return void_level_; }
  int fillets() const { return fillets_; }
  double at(int drow, int dcol) const;  // C(-d) = C(d); 0 beyond max_lag or unmeasured

 private:
  int max_lag_;
  double clip_;
  int reach_;
  double void_level_;
  int fillets_ = 0;
  std::vector<double> sum_, pairs_;  // (2 max_lag + 1)^2, row-major over (drow, dcol)
};

// A calcified sphere of diameter d_mm seen by pixels of pitch_mm (across, columns) and
// step_mm (along, rows): its chord in mm averaged over each pixel (8 x 8 rays), blurred across
// the detector by a Gaussian of blur_px (0: none), over a (2 radius + 1)^2 window.
std::vector<double> sphere_profile(double d_mm, double pitch_mm, double step_mm, int radius,
                                   double blur_px);

// A needle: a cylinder of diam_mm and len_mm, its axis at angle_rad from across the belt
// (columns) toward along it (rows), through the window's centre; its chord averaged over each
// pixel and blurred as sphere_profile's. The test pieces' needle (pipeline/test_pieces.h).
std::vector<double> needle_profile(double len_mm, double diam_mm, double angle_rad, double pitch_mm,
                                   double step_mm, int radius, double blur_px);

// h = (C + ridge) ^-1 s over the window of s ((2 radius + 1)^2, radius <= C's max_lag / 2),
// scaled so that h . s = 1. The ridge (1e-3 of the variance, raised until the system is
// positive definite) keeps a covariance estimated from finitely many pixels invertible.
std::vector<double> whitened_kernel(const TextureCovariance& c, const std::vector<double>& s,
                                    int radius);

// sqrt(h' C h): the kernel's output spread on the texture of `c`.
double kernel_spread(const TextureCovariance& c, const std::vector<double>& taps, int radius);

// The window's radius for a d_mm sphere: the smallest that holds it, at least kBaseKernelRadius.
constexpr int kBaseKernelRadius = 4, kMaxKernelRadius = 8;
int kernel_radius(double d_mm, double pitch_mm, double step_mm);

// The bank for sizes_mm, learned from `c` (each kernel's radius: kernel_radius, at most
// c.max_lag() / 2), with each kernel's spread.
MatchedKernels learn_matched_kernels(const TextureCovariance& c,
                                     const std::vector<double>& sizes_mm, double pitch_mm,
                                     double step_mm, double blur_px);

// Needle kernels of each length along kNeedleDirections directions (every 180 / 8 degrees: a
// whitened needle kernel is narrow, and keeps about 0.9 of its signal-to-noise 11 degrees off
// its axis and 0.5-0.7 at 22), learned from `c` into `k` beside its round ones.
constexpr int kNeedleDirections = 8;
void learn_needle_kernels(const TextureCovariance& c, const std::vector<double>& lengths_mm,
                          const std::vector<double>& diameters_mm, double pitch_mm, double step_mm,
                          double blur_px, MatchedKernels& k);

// z on a copy padded by `radius` with zeros (flat meat off the usable pixels and beyond the
// box), so that a kernel's sums need no bounds: made once for every kernel of a fillet whose
// radius is at most `radius`.
struct PaddedField {
  int rows = 0, cols = 0, radius = 0;
  size_t pitch = 0;       // cols + 2 radius
  std::vector<double> v;  // (rows + 2 radius) x pitch, and a block's slack at the end
};
PaddedField pad_field(const float* z, const uint8_t* use, int rows, int cols, int radius);

// out = sum over the window of h z, z taken as 0 off the usable pixels (where the window
// leaves the fillet the kernel sees flat meat); NaN off them. radius <= f.radius. Returns
// sqrt(sum h^2), the kernel's gain on white noise of unit spread.
double apply_kernel(const PaddedField& f, const uint8_t* use, const std::vector<double>& taps,
                    int radius, std::vector<float>& out);
// The same on z padded for this kernel alone.
double apply_kernel(const float* z, const uint8_t* use, int rows, int cols,
                    const std::vector<double>& taps, int radius, std::vector<float>& out);

// apply_kernel's sum at one usable pixel (r, c) alone (a fragment's few best pixels).
double apply_kernel_at(const float* z, const uint8_t* use, int rows, int cols,
                       const std::vector<double>& taps, int radius, int r, int c);

}  // namespace rangex
