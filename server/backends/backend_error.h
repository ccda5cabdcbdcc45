// A device backend that cannot start, or that failed while running (a failed dispatch,
// a lost device, out of memory): the message names the call and the reason. The engine
// answers by running the batch on the CPU and switching to it.
#pragma once
#include <stdexcept>

namespace rangex {

class BackendError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace rangex
