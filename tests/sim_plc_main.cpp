// The simulated PLC as a process, for tests that run rangexd as one: listens on a free port
// with plant.yaml's default register map, writes the port to PORTFILE, serves until its stdin
// closes, then prints every release it took, one per line:
//   release LANE FIRST LAST CODE SEQUENCE
// and the lanes' states: "state LANE PACKML REASON".
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "sim_plc.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: sim_plc PORTFILE\n");
    return 2;
  }
  rangex::PlcConfig cfg;
  rangex::test::SimPlc plc(cfg);
  {
    std::ofstream f(std::string(argv[1]) + ".tmp");
    f << plc.port() << "\n";
  }
  std::rename((std::string(argv[1]) + ".tmp").c_str(), argv[1]);
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  for (const auto& r : plc.received())
    std::printf("release %d %lld %lld %d %d\n", r.release.lane, (long long)r.release.first_encoder,
                (long long)r.release.last_encoder, int(r.release.code), int(r.sequence));
  for (int lane = 0; lane < 4; ++lane)
    std::printf("state %d %d %d\n", lane, int(plc.lane_state(lane)), int(plc.lane_reason(lane)));
  return 0;
}
