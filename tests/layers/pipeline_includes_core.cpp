// Must compile with the pipeline library's include roots: its own layer and the core below
// it (the control of `layers_hold`).
#include "core/lane_config.h"
#include "pipeline/lane_processor.h"
