// JSON text that never throws on the bytes it is given. A path, a query's value or a name may
// hold bytes that are not UTF-8, and nlohmann's dump() throws on them: a learning ended after
// all its work, an HTTP client got no answer. Such bytes are written as U+FFFD.
#pragma once
#include <nlohmann/json_fwd.hpp>
#include <string>

namespace rangex {

// A string as a JSON string literal, for JSON written by hand: quotes, backslashes and control
// characters escaped.
std::string json_text(const std::string& s);
// A JSON value's text; indent as dump()'s (-1: one line).
std::string json_dump(const nlohmann::json& j, int indent = -1);

}  // namespace rangex
