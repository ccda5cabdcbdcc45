// Must not compile: a plantdb file that reaches up into the service, which uses plantdb. The
// test `layers_hold_plantdb` compiles it with plantdb's include roots (its layer, the store
// and core) and expects the service header not to be found.
#include "service/engine.h"
