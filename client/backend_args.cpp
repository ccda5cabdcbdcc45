#include "backend_args.h"

#include <algorithm>
#include <thread>

#include "core/error.h"

namespace rangex::cli {

namespace {
void check_name(const std::string& n, bool all_allowed) {
  if (n == "auto" || n == "cpu" || n == "cpu-portable" || n == "opencl" || n == "vulkan" ||
      (all_allowed && n == "all"))
    return;
  fail("--backend must be ", all_allowed ? "all, " : "",
       "auto, cpu, cpu-portable, opencl or vulkan (got '", n, "')");
}
}  // namespace

BackendRequest backend_request(const Args& a, const std::string& def) {
  BackendRequest r;
  r.name = a.get("backend", def);
  check_name(r.name, false);
  r.device = a.get("device", "");
  r.threads = int(a.integer("threads", long(std::max(1u, std::thread::hardware_concurrency()))));
  if (r.threads < 1) fail("--threads must be >= 1 (got ", r.threads, ")");
  return r;
}

std::vector<std::string> backend_names(const std::string& value) {
  check_name(value, true);
  if (value != "all") return {value};
  std::vector<std::string> out;
  for (const BackendProbe& p : probe_backends()) {
    if (p.available)
      out.push_back(p.name);
    else
      std::fprintf(stderr, "backend %s left out: %s\n", p.name.c_str(), p.detail.c_str());
  }
  return out;
}

}  // namespace rangex::cli
