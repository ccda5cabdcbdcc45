// Shared by every rangex compute shader: the tables and push constants written once for
// C++, OpenCL C and GLSL; frames read as 32-bit words (no 8-bit storage feature needed); NaN.
#include "shared/fillet_tables.h"
#include "shared/lane_tables.h"
#include "shared/push_constants.h"
#include "shared/stripe_methods.h"

#define kNaN uintBitsToFloat(0x7fc00000u)
