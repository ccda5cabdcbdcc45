// Shared by every rangex compute shader: the tables and push constants written once for
// C++, OpenCL C and GLSL; frames read as 32-bit words (no 8-bit storage feature needed); NaN.
#include "shared/lane_tables.h"
#include "shared/push_constants.h"
#include "shared/fillet_tables.h"

#define METHOD_CENTROID 0
#define METHOD_SQUARED 1
#define METHOD_BINARY 2
#define METHOD_GAUSSIAN3 3
#define METHOD_PARABOLA 4
#define METHOD_SHIFTED 5
#define METHOD_MODIFIED 6

#define kNaN uintBitsToFloat(0x7fc00000u)
