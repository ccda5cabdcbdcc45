// A LineScan as the server takes it in: its bytes moved out of the message, not copied.
#pragma once
#include "core/incoming_line.h"
#include "rangex/v1/rangex.pb.h"

namespace rangex {

IncomingLine take_line(v1::LineScan& line);

}  // namespace rangex
