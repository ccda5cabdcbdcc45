// One exception type for every refused input: the message names what is wrong.
#pragma once
#include <sstream>
#include <stdexcept>
#include <string>

namespace rangex {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// fail("lane ", id, ": frame is ", w, "x", h) throws Error with the pieces joined.
template <typename... Parts>
[[noreturn]] void fail(const Parts&... parts) {
  std::ostringstream os;
  (os << ... << parts);
  throw Error(os.str());
}

}  // namespace rangex
