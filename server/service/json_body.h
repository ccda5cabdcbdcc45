// The text of a JSON answer. An answer may name what a request sent (a query's value, a
// body's key), and a request may send any bytes: those that are not UTF-8 are written as
// U+FFFD. nlohmann's dump() throws on them, which left the client with no answer at all.
#pragma once
#include <nlohmann/json_fwd.hpp>
#include <string>

namespace rangex {

std::string json_body(const nlohmann::json& j);

}  // namespace rangex
