// A string as a JSON string literal, for JSON written by hand: quotes, backslashes and control
// characters escaped, and bytes that are not UTF-8 (a path may hold any) replaced by U+FFFD
// rather than thrown on.
#pragma once
#include <string>

namespace rangex::cli {

std::string json_text(const std::string& s);

}  // namespace rangex::cli
