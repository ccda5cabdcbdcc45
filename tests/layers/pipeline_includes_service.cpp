// Must not compile: a pipeline file that reaches up into the service layer. The test
// `layers_hold` compiles it with the pipeline library's include roots and expects the
// service header not to be found.
#include "service/engine.h"
