// One lane's dual-energy decomposition as the kernels read it (C++, OpenCL C, GLSL std430):
// doubles only. Built on the host from the lane's dual-energy calibration
// (calib/dual_energy_fit.h); the CPU reference is pipeline/dual_energy.h.
#ifndef RANGEX_DUAL_ENERGY_H
#define RANGEX_DUAL_ENERGY_H

#ifdef __cplusplus
namespace rangex::kernel {
#endif

// The forward model: each layer's log attenuation as a polynomial of degree DE_DEGREE in the
// basis lengths, scaled u = A / DE_A_MM (mm of A-150), v = B / DE_B_MM (mm of aluminium);
// terms u^i v^j by total degree, then by falling i: 1, u v, u2 uv v2, u3 u2v uv2 v3, ...
// A pixel's (A, B) is its inverse, by Newton's method.
#define DE_DEGREE 5
#define DE_TERMS 21
#define DE_A_MM 50.0
#define DE_B_MM 5.0
#define DE_NEWTON 8

struct DualEnergyK {
  double low[DE_TERMS];   // ln(open / I) of the low layer from (u, v)
  double high[DE_TERMS];  // of the high layer
  // Row-major inverse of [[a_lean a_fat a_bone] [b_lean b_fat b_bone] [1 1 1]]: each
  // material's basis lengths per mm, and the laser's thickness as their sum.
  double minv[9];
  double basis[6];  // lean, fat, bone per mm: (mm of A-150, mm of Al) each
  double var_a;     // the calibration's own error at the wedge's steps (A, B recovered), mm^2
  double var_b;
  double gain_low;  // each layer's noise: var(DN) = gain x DN + var_e
  double gain_high;
  double var_e_low;  // electronic noise, DN^2
  double var_e_high;
  double var_t;  // the laser thickness's variance, mm^2
};

#ifdef __cplusplus
}  // namespace rangex::kernel
#endif

#endif
