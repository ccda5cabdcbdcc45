// The decisions' names as rangex writes them (the store, JSON, the command line) and their
// rangex.v1 values: the one place where both are written.
#pragma once
#include <string_view>

#include "rangex/v1/rangex.pb.h"

namespace rangex {

// DECISION_UNSPECIFIED for a name that is none of "pass", "reject", "not_inspected".
v1::Decision decision_from_name(std::string_view name);
// "" for DECISION_UNSPECIFIED and values this build does not know.
const char* decision_name(v1::Decision d);

}  // namespace rangex
