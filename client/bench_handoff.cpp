#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#include "commands.h"
#include "core/error.h"

namespace fs = std::filesystem;

namespace rangex::cli {

int run_bench_binary(char** argv) {
  // Beside rangexctl (installed, or the build tree), else where this build put it.
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  std::string path = ec ? "" : (self.parent_path() / "rangex-bench").string();
  if (path.empty() || access(path.c_str(), X_OK) != 0) path = RANGEX_BENCH_PATH;
  if (access(path.c_str(), X_OK) != 0)
    fail(argv[1], " runs in rangex-bench, which is neither beside rangexctl nor at ", path,
         " (build the rangex-bench target)");
  argv[0] = const_cast<char*>(path.c_str());
  execv(path.c_str(), argv);
  fail("cannot start ", path, ": ", std::strerror(errno));
}

}  // namespace rangex::cli
