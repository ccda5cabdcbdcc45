// "host:port" read strictly: std::stoi reads "80x8" as 80, and a plant's typo would then
// bind or connect elsewhere without a word.
#pragma once
#include <string>

namespace rangex {

// The port of `address` (after its last ':'), or -1 unless it is 1 to 5 digits naming
// 0..65535.
int port_of(const std::string& address);

}  // namespace rangex
