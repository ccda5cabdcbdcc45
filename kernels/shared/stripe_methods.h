// The stripe extraction methods' numbers, written once for C++ (StripeMethod in
// server/core/stripe_params.h takes its values from here), OpenCL C and GLSL.
#ifndef RANGEX_STRIPE_METHODS_H
#define RANGEX_STRIPE_METHODS_H

#define METHOD_CENTROID 0
#define METHOD_SQUARED 1
#define METHOD_BINARY 2
#define METHOD_GAUSSIAN3 3
#define METHOD_PARABOLA 4
#define METHOD_SHIFTED 5
#define METHOD_MODIFIED 6

#endif
