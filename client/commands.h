// rangexctl subcommands; each takes the arguments after its name and returns an exit code.
#pragma once
#include <string>

#include "core/plant_config.h"

namespace rangex::cli {

int cmd_simulate(int argc, char** argv);
int cmd_extract(int argc, char** argv);
int cmd_process(int argc, char** argv);
int cmd_eval(int argc, char** argv);
int cmd_eval_matrix(int argc, char** argv);
int cmd_learn(int argc, char** argv);
int cmd_calib(int argc, char** argv);
int cmd_fit(int argc, char** argv);
int cmd_feed(int argc, char** argv);
int cmd_watch(int argc, char** argv);
int cmd_status(int argc, char** argv);
int cmd_fillets(int argc, char** argv);
int cmd_image(int argc, char** argv);
int cmd_calib_remote(int argc, char** argv);
// calib simulate|camera|staircase|xray|registration|validate; -1 for another verb.
int cmd_calib_solve(int argc, char** argv);
int cmd_lanes(int argc, char** argv);
int cmd_learned(int argc, char** argv);
int cmd_audit(int argc, char** argv);
int cmd_db(int argc, char** argv);
int cmd_token(int argc, char** argv);
int cmd_plc_sim(int argc, char** argv);
int cmd_record(int argc, char** argv);
int cmd_verify(int argc, char** argv);
int cmd_fake_lane(int argc, char** argv);

// bench, bench-server and soak run in rangex-bench (client/bench/), which holds a server in
// process: rangexctl hands the command line over to it.
int run_bench_binary(char** argv);

// --config, else $RANGEX_CONFIG, else ./config/plant.yaml, else the source tree's default.
std::string config_path(const std::string& option_value);
PlantConfig load_config(const std::string& option_value);

}  // namespace rangex::cli
