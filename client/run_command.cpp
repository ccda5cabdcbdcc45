#include "run_command.h"

#include <cstdio>
#include <exception>

#include "core/error.h"

namespace rangex::cli {

int run_command(const char* cmd, const std::function<int()>& body) {
  try {
    return body();
  } catch (const rangex::Error& e) {
    std::fprintf(stderr, "rangexctl %s: error: %s\n", cmd, e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rangexctl %s: internal error: %s\n", cmd, e.what());
    return 3;
  }
}

}  // namespace rangex::cli
