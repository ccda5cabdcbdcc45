#include "service/request_end.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <string>

namespace rangex {

size_t announced_body(std::string_view head) {
  std::string lower(head);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (lower.find("\r\ntransfer-encoding:") != std::string::npos) return SIZE_MAX;
  const size_t at = lower.find("\r\ncontent-length:");
  if (at == std::string::npos) return 0;
  size_t k = at + 17;
  while (k < lower.size() && (lower[k] == ' ' || lower[k] == '\t')) ++k;
  size_t n = 0, digits = 0;
  for (; k < lower.size() && std::isdigit(static_cast<unsigned char>(lower[k])); ++k, ++digits) {
    if (n > SIZE_MAX / 20) return SIZE_MAX;
    n = n * 10 + size_t(lower[k] - '0');
  }
  if (digits == 0) return SIZE_MAX;
  while (k < lower.size() && (lower[k] == ' ' || lower[k] == '\t')) ++k;
  return lower.compare(k, 2, "\r\n") == 0 ? n : SIZE_MAX;
}

RequestEnd request_end(std::string_view got, size_t max_head, size_t max_body) {
  RequestEnd e;
  const size_t end = got.substr(0, max_head + 4).find("\r\n\r\n");
  if (end == std::string_view::npos) {
    e.too_large = got.size() > max_head;
    return e;
  }
  const size_t head = end + 4;
  const size_t body = announced_body(got.substr(0, head));
  e.bytes = head + (body <= max_body ? body : 0);
  e.complete = got.size() >= e.bytes;
  return e;
}

}  // namespace rangex
