// The scalar arguments of each compute shader (Vulkan push constants), written once for C++
// and GLSL; the OpenCL kernels take the same values as plain arguments.
#ifndef RANGEX_PUSH_CONSTANTS_H
#define RANGEX_PUSH_CONSTANTS_H

#ifdef __cplusplus
namespace rangex::kernel {
#endif

struct StripePush {
  int count;  // frames
  int width;
  int height;
  int pad0;
};

struct RectifyPush {
  int count;  // frames
  int width;
  int pad0;
  int pad1;
};

struct FusePush {
  int lines;
  int width;
  int grid_n;
  int pad0;
};

struct ProjectPush {
  int lines;
  int grid_n;
  int pixels;
  int pad0;
};

struct FilletPush {
  int fillets;
  int pad0;
  int pad1;
  int pad2;
};

// The dual-energy stages: a batch of pixels; the bone's soft-tissue density variance.
struct DualEnergyPush {
  int pixels;
  int pad0;
  double density_var;
};

#ifdef __cplusplus
static_assert(sizeof(StripePush) == 16 && sizeof(RectifyPush) == 16 && sizeof(FusePush) == 16 &&
                  sizeof(ProjectPush) == 16 && sizeof(FilletPush) == 16 &&
                  sizeof(DualEnergyPush) == 16,
              "push constants must match the shaders' blocks");
}  // namespace rangex::kernel
#endif

#endif
