// Whether text is UTF-8. YAML is Unicode text, and what plant.yaml names (the plant, its lanes,
// cameras, users) is served as protobuf strings, which must be UTF-8: a plant named with the
// byte 0xFF left every gRPC client with "No message returned" for the server's info.
#pragma once
#include <cstddef>
#include <string>
#include <string_view>

namespace rangex {

// The offset of the first byte that does not begin or continue a well-formed UTF-8 sequence
// (RFC 3629: no overlong forms, no surrogates, nothing past U+10FFFF), or npos.
size_t invalid_utf8_at(std::string_view s);
// s with each byte that invalid_utf8_at would stop at written as U+FFFD: for text from outside
// (a camera's vendor name, a database's message, a path) on its way into a protobuf string.
std::string valid_utf8(std::string_view s);

}  // namespace rangex
