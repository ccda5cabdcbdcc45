// A command run as every rangex tool runs one: its own exit code; 1 for a rangex::Error (a
// message the user can act on), 3 for anything else (a fault of ours), each printed as
// "rangexctl CMD: ...".
#pragma once
#include <functional>

namespace rangex::cli {

// `cmd`: the command's name; `body` returns the exit code (2: unknown command or usage).
int run_command(const char* cmd, const std::function<int()>& body);

}  // namespace rangex::cli
