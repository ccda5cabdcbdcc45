// A line without a line: `plc-sim` (a simulated PLC taking rangexd's releases over Modbus TCP)
// and `fake-lane` (a lane's three GigE Vision devices serving a recording), for the demo and
// an integrator's dry run of a plant.yaml. Both serve until SIGINT or SIGTERM.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <thread>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "core/recording.h"
#include "plc/plc_simulator.h"
#include "sensors/fake_devices.h"

namespace rangex::cli {

namespace {

std::atomic<bool> stopping{false};

void on_signal(int) {
  stopping = true;
}

// Sleeps until SIGINT or SIGTERM, calling `every` each `period_s`.
template <typename F>
void serve(double period_s, F every) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  auto next = std::chrono::steady_clock::now() + std::chrono::duration<double>(period_s);
  while (!stopping) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (std::chrono::steady_clock::now() >= next) {
      every();
      next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(period_s));
    }
  }
}

}  // namespace

int cmd_plc_sim(int argc, char** argv) {
  const Args a(argc, argv, 2, {"list"}, {"config", "port", "port-file", "every", "registers"});
  a.expect_positionals(
      0, "plc-sim [--port P] [--port-file F] [--registers N] [--list] [--config ...]");
  const PlantConfig plant = load_config(a.get("config", ""));
  // The plant's register map; the port from --port, else plant.yaml's plc address, else free.
  int port = int(a.integer("port", 0));
  if (!a.has("port") && plant.plc.enabled())
    port = std::stoi(plant.plc.address.substr(plant.plc.address.rfind(':') + 1));
  SimPlc plc(plant.plc, port);
  // A PLC program that maps fewer holding registers refuses writes past them (exception 2):
  // an integrator's dry run of plant.yaml's plc section against the program's map.
  const int64_t registers = a.integer("registers", 65536);
  if (registers < 1 || registers > 65536)
    fail("--registers must be 1..65536 (got ", registers, ")");
  plc.set_registers(int(registers));
  std::printf(
      "plc-sim: a simulated PLC on 127.0.0.1:%d (ring at %d, %d slots; holding registers "
      "0..%lld; docs/plc.md)\n",
      plc.port(), plant.plc.ring_base, plant.plc.ring_slots, (long long)registers - 1);
  std::fflush(stdout);
  if (a.has("port-file")) {
    const std::string f = a.get("port-file", "");
    std::ofstream(f + ".tmp") << plc.port() << "\n";
    std::rename((f + ".tmp").c_str(), f.c_str());
  }
  size_t shown = 0;
  serve(std::stod(a.get("every", "5")), [&] {
    const auto got = plc.received();
    if (got.size() == shown) return;
    shown = got.size();
    int by[5] = {};
    for (const auto& r : got) ++by[int(r.release.code)];
    std::printf("plc-sim: %zu releases: %d pass, %d reject, %d not inspected, %d late\n",
                got.size(), by[1], by[2], by[3], by[4]);
    std::fflush(stdout);
  });
  if (a.flag("list")) {
    for (const auto& r : plc.received())
      std::printf("release %d %lld %lld %s %d\n", r.release.lane,
                  (long long)r.release.first_encoder, (long long)r.release.last_encoder,
                  release_code_name(r.release.code), int(r.sequence));
    for (const LaneConfig& l : plant.lanes)
      std::printf("state %d %s %d\n", l.id, packml_name(plc.lane_state(l.id)),
                  int(plc.lane_reason(l.id)));
  }
  return 0;
}

int cmd_fake_lane(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"lane", "addresses", "period-us", "lead"});
  const std::string dir = a.positional(0, "RECORDING");
  a.expect_positionals(1,
                       "fake-lane RECORDING --addresses CAM0,CAM1,XRAY [--lane L] "
                       "[--period-us 10000] [--lead 200]");
  const RecordingReader rec(dir);
  const int lane = int(a.integer("lane", rec.info().lanes.at(0)));
  std::vector<std::string> addrs;
  {
    std::string list = a.require("addresses"), item;
    for (char c : list + ",") {
      if (c != ',') {
        item += c;
      } else if (!item.empty()) {
        addrs.push_back(item);
        item.clear();
      }
    }
  }
  if (addrs.size() != 3) fail("--addresses takes three: cam0, cam1, xray (got ", addrs.size(), ")");
  LoopbackAddresses lo(addrs);
  if (!lo.ok()) fail(lo.error());
  const int period_us = int(a.integer("period-us", 10000));
  ServedLane served(rec, lane, int(a.integer("lead", 200)));
  std::vector<std::unique_ptr<FakeDevice>> devices;
  std::unique_ptr<FakeEncoder> encoder;
  for (int d = 0; d < 3; ++d)
    devices.push_back(std::make_unique<FakeDevice>(
        addrs[size_t(d)], "fake" + std::to_string(lane) + std::to_string(d), period_us,
        [&, d](int64_t, uint8_t* out, size_t bytes) {
          // The belt runs on through the recording's last line, again and again.
          const int64_t n = encoder ? encoder->pulse() : 0;
          served.fill(d, n % (served.lines() + 400), out, bytes);
        }));
  encoder = std::make_unique<FakeEncoder>(devices);
  std::printf(
      "fake-lane: lane %d of %s on %s, %s, %s (TriggerSource Software: plant.yaml "
      "sources with trigger: encoder, trigger_line: Software)\n",
      lane, dir.c_str(), addrs[0].c_str(), addrs[1].c_str(), addrs[2].c_str());
  std::fflush(stdout);
  int64_t last = 0;
  serve(5, [&] {
    const int64_t p = encoder->pulse();
    if (p != last) std::printf("fake-lane: %lld lines\n", (long long)p);
    last = p;
    std::fflush(stdout);
  });
  encoder.reset();
  return 0;
}

}  // namespace rangex::cli
