// Shared by every rangex OpenCL kernel: doubles (fusion and projection follow the CPU
// reference, which computes in double) and no contraction of a * b + c into fma, so that
// float results round as the CPU reference's do.
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF
#include "shared/fillet_tables.h"
#include "shared/lane_tables.h"
#include "shared/stripe_methods.h"
