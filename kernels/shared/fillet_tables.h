// A batch of fillets as the pseudo-X-ray kernels read it, written once for C++, OpenCL C and
// GLSL (std430): fillet f owns pixels offsets[f] .. offsets[f + 1] - 1 of the flat per-pixel
// arrays (thickness, X-ray, use), and one model.
#ifndef RANGEX_FILLET_TABLES_H
#define RANGEX_FILLET_TABLES_H

#ifdef __cplusplus
namespace rangex::kernel {
#endif

// The fillet's model ln P = b0 + b1 T; the Tukey weights of one IRLS iteration (scale <= 0:
// every weight 1, the ordinary least-squares start); its noise model sigma_ln(P) =
// sqrt(a / P + b / P^2) for the z image (a = b = 0: no z).
struct FilletModelK {
  double b0;
  double b1;
  double scale;
  double c;
  double noise_a;
  double noise_b;
};

// The weighted sums of one IRLS iteration, in this order per fillet.
#define IRLS_SUMS 6  // sum w, w T, w lnI, w T^2, w T lnI, w r^2

#ifdef __cplusplus
static_assert(sizeof(FilletModelK) == 48, "std430 layout");
}  // namespace rangex::kernel
#endif

#endif
