// SHA-256 as lower-case hex (OpenSSL): the record chain's links and bearer tokens' digests.
#pragma once
#include <string>

namespace rangex {

std::string sha256_hex(const std::string& data);

}  // namespace rangex
