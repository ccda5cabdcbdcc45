// Must compile with plantdb's include roots: its own layer, and the store and core below it
// (the control of `layers_hold_plantdb`).
#include "core/plant_config.h"
#include "plantdb/forwarder.h"
#include "store/store.h"
