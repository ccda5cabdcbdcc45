// One exception type for every refused input: the message names what is wrong. Its
// refinements let the service answer with the right status: NotFound (an unknown lane or
// calibration), AlreadyExists (a calibration id taken), FailedPrecondition (a gate) and
// Unavailable (a peer it needs, such as the plant-wide database, does not answer).
#pragma once
#include <sstream>
#include <stdexcept>
#include <string>

namespace rangex {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
class NotFound : public Error {
 public:
  using Error::Error;
};
class AlreadyExists : public Error {
 public:
  using Error::Error;
};
class FailedPrecondition : public Error {  // refused in the current state (a gate)
 public:
  using Error::Error;
};
class Unavailable : public Error {  // a peer does not answer: the same request may work later
 public:
  using Error::Error;
};

template <typename... Parts>
std::string join(const Parts&... parts) {
  std::ostringstream os;
  (os << ... << parts);
  return os.str();
}

// fail("lane ", id, ": frame is ", w, "x", h) throws Error with the pieces joined.
template <typename... Parts>
[[noreturn]] void fail(const Parts&... parts) {
  throw Error(join(parts...));
}
template <typename... Parts>
[[noreturn]] void fail_not_found(const Parts&... parts) {
  throw NotFound(join(parts...));
}
template <typename... Parts>
[[noreturn]] void fail_exists(const Parts&... parts) {
  throw AlreadyExists(join(parts...));
}

}  // namespace rangex
