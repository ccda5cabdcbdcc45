// rangex-bench: the benchmarks and the soak, which run the line path, the backends and
// rangexd in process. `rangexctl bench|bench-server|soak` hands its command line over here,
// so that rangexctl itself links no server.
#include <cstdio>
#include <cstring>

#include "bench/bench_commands.h"
#include "commands.h"
#include "run_command.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(
        "usage: rangex-bench bench|bench-server|bench-gige|bench-forward|soak [options] (see "
        "rangexctl --help)\n",
        stderr);
    return 2;
  }
  using namespace rangex::cli;
  const char* cmd = argv[1];
  return run_command(cmd, [&] {
    if (!std::strcmp(cmd, "bench")) return cmd_bench(argc, argv);
    if (!std::strcmp(cmd, "bench-server")) return cmd_bench_server(argc, argv);
    if (!std::strcmp(cmd, "soak")) return cmd_soak(argc, argv);
    if (!std::strcmp(cmd, "bench-gige")) return cmd_bench_gige(argc, argv);
    if (!std::strcmp(cmd, "bench-forward")) return cmd_bench_forward(argc, argv);
    // bench-gige's fakes, in a process of their own (rangexctl fake-lane's command).
    if (!std::strcmp(cmd, "fake-lane")) return cmd_fake_lane(argc, argv);
    std::fprintf(stderr,
                 "rangex-bench: unknown command '%s' (bench, bench-server, bench-gige, "
                 "bench-forward, soak)\n",
                 cmd);
    return 2;
  });
}
