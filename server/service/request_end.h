// Where the HTTP request at the front of a connection's bytes ends: its head (through the
// empty line) and the small body its Content-Length announces. The gate waits for both
// before a worker serves the request, so a slow body holds no worker, as a slow head does
// not. A body over max_body, or one sent chunked, ends the request at its head: the worker
// refuses it (413) without reading it.
#pragma once
#include <cstddef>
#include <string_view>

namespace rangex {

struct RequestEnd {
  bool complete = false;   // bytes: the head and its body are all there
  bool too_large = false;  // no head within max_head bytes
  size_t bytes = 0;
};

RequestEnd request_end(std::string_view got, size_t max_head, size_t max_body);

// The body a request head announces: its Content-Length (0 without one); SIZE_MAX for one
// sent chunked or a length that is not a number.
size_t announced_body(std::string_view head);

}  // namespace rangex
