// rangex-bench's commands (rangexctl bench|bench-server|soak hand over to it): each takes
// the arguments after its name and returns an exit code.
#pragma once

namespace rangex::cli {

int cmd_bench(int argc, char** argv);
int cmd_bench_server(int argc, char** argv);
int cmd_soak(int argc, char** argv);
int cmd_bench_gige(int argc, char** argv);
int cmd_bench_forward(int argc, char** argv);

}  // namespace rangex::cli
