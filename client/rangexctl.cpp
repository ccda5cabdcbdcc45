// rangexctl: the command-line client: offline tools on recordings and simulations, and the
// gRPC client of a running rangexd (feed, watch, calibrations, status).
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "commands.h"
#include "core/error.h"
#include "core/heap_trim.h"
#include "run_command.h"
#include "usage_entries.h"

namespace {
constexpr const char* kUsage = R"(usage: rangexctl <command> [options]

commands:
  simulate --out DIR [--lanes N] [--fillets M] [--seed S] [--physics VARIANT.yaml] [--clean]
      simulate a plant and write a recording with ground truth (--physics: another plant's
      physics, config/variants/*.yaml)
  extract DIR --lane L --camera C [--method NAME] --out peaks.csv [--config ...]
      stripe rows of one camera as CSV (frame,column,row; row empty where invalid)
  process DIR --out OUT [--method NAME] [--images all|rejects|none] [--config ...]
      replay a recording through the pipeline and inspect every fillet
  process --simulate --out OUT [--lanes N] [--fillets M] [--seed S] [--physics F] [--images ...]
      simulate a plant in memory (no recording) and inspect it; prints the evaluation
      (both: [--backend auto|cpu|opencl|vulkan] [--device D] for the line stages)
  eval DIR OUT [--json]   |   eval OUT [--json]
      compare processed output with the truth of its recording (or of its simulation)
  eval-matrix --out DIR [--variants DIR] [--only A,B] [--fillets N] [--seed S] [--learn N] [--frr N]
                  [--bones N]
      each plant variant (config/variants) calibrated from its own scenes, simulated,
      inspected and evaluated beside the X-ray-only baseline (a benchmark: minutes each);
      --frr N and --bones N: more clean and more bony fillets with the learned thresholds
  learn RECORDING --out PLANT.yaml [--target-frr 0.003] [--confidence 0.9] [--lanes L,..]
        [--calibration F] [--report DIR] [--version NAME] [--excess-ratio 2] [--check REC] [--force]
        [--keep LANE:FILLET,...] [--tradeoff 0.001,0.01] [--tail-from 0.5]
  learn --simulate --out PLANT.yaml [--lanes N] [--fillets 40] [--seed S] [--physics F] [...]
      learn each lane's detection thresholds from a recording of clean product: an
      extreme-value model per thickness band, the sensitivity it buys (test pieces), a
      report (JSON, PNG); writes a copy of the plant configuration that uses them;
      --tradeoff: what other false-reject targets would buy on the same fillets;
      --tail-from: a statistic whose top its whole fit does not hold is fitted above that
      quantile of it (0: never);
      --simulate: from clean product simulated in memory instead of a recording
  fit FILE.csv [--c C] [--degree 1|2] [--json]
      robust fit ln I = b0 + b1 T (Tukey biweight) of a two-column CSV with a header
      (--degree 2: + b2 T^2, the parabola of a hardened beam)
  calib scatter DIR [--lines N] [--config ...]
      fit the scattering constants K1, K2 per camera from a recording with truth

calibration of a lane (docs/calibration.md); each solve reads --calibration FILE (else the
plant's lane), writes the updated calibration to --out FILE and its report to FILE.reports/:
  calib simulate targets|staircase|pins|blocks OUT [--lane L] [--rig-seed S] [--cam N]
      calibration scans from the simulator (--rig-seed: a rig that differs from plant.yaml)
  calib camera DIR [--cam N] [--fix skew,k1,k2,p1,p2,k3] [--skip-unfound]
      intrinsics and distortion from target images (DIR/board.yaml describes the board;
      --fix: parameters held, skew and distortion terms at 0)
  calib staircase SCAN     both cameras' poses from a staircase scan (SCAN/staircase.yaml)
  calib xray SCAN | --pins CSV [--hold-pitch] [--row-offsets]
      fan-beam geometry and blur from a pin-phantom scan (SCAN/pin_phantom.yaml) or pins
  calib registration SCAN  delay and plane angles from blocks (SCAN/blocks.yaml)
  calib validate SCAN --calibration FILE
      measure a known object (staircase, blocks) with a candidate calibration

benchmarks (each beside its baseline, measured in the same run):
  bench [--frames N]
      stripe extraction and inspection throughput beside their baselines
  bench --path [--lanes 1,4,16] [--lines N] [--batch B] [--threads T]
      the whole CPU line path stage by stage, per line and per fillet, each stage's share
      and its fraction of its own memory bound; the scaling over T threads
  bench --backend cpu|opencl|vulkan|all [--device D] [--lanes 1,4,16] [--batches 1,16,64,256]
      each line stage on each backend (upload / compute / download), the line path with two
      batches in flight, beside the CPU backend; a device's stripe stage against its
      host-to-device bandwidth

  bench-server [--lines N] [--backend NAME|all] [--lanes 1,4,16] [--rate R [--seconds S]]
               [--path] [--capacity]
      lines/s through gRPC on loopback for 1, 4, 16 lanes beside the in-process pipeline, and
      the latency from a fillet's last line to its decision (--rate: lines/s per lane;
      --seconds: a long run, resident memory by minute; --path: the server's stages)

  bench-forward --db CONNSTR [--fillets 5000] [--lanes 8] [--rate 1250] [--seconds 30]
      forwarding to the plant-wide PostgreSQL beside the store's own write rate: a backlog
      drained, and the lag while the lanes decide fillets at their rate

  bench-gige [--fillets 3] [--period-us 2000]
      a lane over GigE Vision (fake devices in a process of their own, root for their
      loopback addresses) against the replay of the same recording: CPU time a line, lines/s,
      bytes copied a line

  soak [--minutes 30] [--lanes 4] [--rate 600] [--backend NAME]
      rangexd fed a simulated plant at a fixed rate with a subscriber and queries: per minute
      lines, decisions, fail-safe rejects, decision p50/p99 and resident memory; lines lost

records, the plant-wide database and access:
  audit verify [--data DIR]   the store's hash chain over every decision and audit entry:
                              verified with its head, or the first broken link and why
  audit export [--data DIR] [--from-ns T] [--to-ns T] --out FILE.jsonl
      the links of a time range with their contents and the chain's head (a chain proof)
  audit verify --db CONNSTR   every server's chain in the plant-wide PostgreSQL
  db migrate --db CONNSTR [--to N]   apply the plant-wide schema's migrations
  db status --db CONNSTR      the schema's version and each server's forwarding
  db prune --db CONNSTR --keep-days N | --before DAY [--dry-run]
                              drop whole UTC days, keeping each server's chain whole

  token --name NAME --role viewer|operator|engineer|admin [--out FILE]
      a new bearer token, and the line (its SHA-256) that grants it in plant.yaml

a line without a line (until SIGINT/SIGTERM; docs/sensors.md, docs/plc.md):
  plc-sim [--port P] [--port-file F] [--registers N] [--list]
      a simulated PLC taking rangexd's releases over Modbus TCP with plant.yaml's register
      map (the port from --port, else plc.address); --registers: its program maps holding
      registers 0..N-1 only (65536), as a PLC's may; --list: every release at the end
  fake-lane RECORDING --addresses CAM0,CAM1,XRAY [--lane L] [--period-us 10000] [--lead 200]
      a lane's three GigE Vision devices (Aravis fake cameras on loopback addresses, added
      to lo) serving the recording's frames, pulsed in step by an encoder of their own

server commands (--server HOST:PORT, default: plant.yaml's listen address; over TLS:
  --ca CA.pem [--cert C.pem --key K.pem] [--token-file F] [--tls-name NAME], or
  RANGEX_CA, RANGEX_CERT, RANGEX_KEY, RANGEX_TOKEN / RANGEX_TOKEN_FILE):
  feed (--recording DIR | --simulate [--lanes N] [--fillets M] [--seed S]) [--rate LINES/S]
      stream line scans into rangexd (rate per lane; default as fast as the server takes them);
      [--window N] [--reconnect-for S] [--settle-for S]: at the end, waits until every lane's
      outcomes are stored; exit 5: lines refused, 6: lanes not settled (their counts named)
  watch [--lane L] [--decision pass|reject|not_inspected] [--count N] [--seconds S]
      [--reconnect-for S]: live fillet decisions, each once; when the stream is lost, connects
      again (giving up after S s, default 60; 0: at once) and shows from the store what was
      decided meanwhile
  status [--json]             statistics: lines/s, latencies, queue, drops by reason
  fillets [--lane L] [--limit N] [--from-ns T] [--to-ns T]  |  fillets --uid U
  image --uid U [--kind overlay|xray|thickness|pseudo_xray|residual] --out FILE.png
  calib upload --lane L --id ID --file CAL.yaml [--report R.json]  (default: CAL.yaml.reports/)
  calib list [--lane L]  |  calib show --lane L --id ID  |  calib activate --lane L --id ID [--force]
      activation refuses a set whose report is missing or failed unless --force (admin role)
  record start [--lanes 0,1] --minutes N [--name NAME]  |  record stop  |  record status
      record a shift on the server (<data>/recordings/NAME/laneL, one recording a lane, for
      `process`); refused when its minutes at the lanes' rate would not fit the disk
  verify start --lane L --piece NAME --x-mm X [--tolerance-mm T] [--fillets N]  |  verify list
      a verification run (HACCP): the lane's next fillets must show the declared test piece
      where it was placed; pass or fail is audited with who, when and the fillet's images
  lanes  |  lanes set --lane L [--z-threshold Z] [--min-area-mm2 A] [--floor-mm F]
  learned upload --lane L --id ID --file PLANT.yaml [--report R.json]  (learn's output)
  learned list [--lane L] [--full]  |  learned activate --lane L --id ID [--force]
  learned learn --lane L [--fillets 40] [--id ID] [--target-frr F] [--timeout S]
                [--tradeoff 0.001,0.01]
      learned thresholds as versions: learn from the lane's next fillets live, upload what
      rangexctl learn wrote; activation refuses a failed report unless --force (admin role)

stripe methods: centroid, squared, binary, gaussian3, parabola, shifted, modified
)";
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  // `rangexctl CMD ... --help`: that command's entries of the usage (an unknown command is
  // refused below, as without --help).
  for (int i = 2; i < argc; ++i)
    if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      const std::string entries = rangex::cli::usage_of(kUsage, argv[1]);
      if (entries.empty()) break;
      std::printf("usage: rangexctl %s ...\n\n%s", argv[1], entries.c_str());
      return 0;
    }
  // rangexd's heap policy (core/heap_trim.h), without its periodic trim: under glibc's
  // own, each lane's inspection buffers were mapped and faulted in anew, and the lanes'
  // threads waited on each other's page faults (`process --simulate --lanes 4`: 105-183 ms a
  // fillet against 63-88).
  rangex::set_server_heap_policy();
  using namespace rangex::cli;
  const char* cmd = argv[1];
  return run_command(cmd, [&] {
    if (!std::strcmp(cmd, "simulate")) return cmd_simulate(argc, argv);
    if (!std::strcmp(cmd, "extract")) return cmd_extract(argc, argv);
    if (!std::strcmp(cmd, "process")) return cmd_process(argc, argv);
    if (!std::strcmp(cmd, "eval")) return cmd_eval(argc, argv);
    if (!std::strcmp(cmd, "eval-matrix")) return cmd_eval_matrix(argc, argv);
    if (!std::strcmp(cmd, "learn")) return cmd_learn(argc, argv);
    if (!std::strcmp(cmd, "calib")) return cmd_calib(argc, argv);
    if (!std::strcmp(cmd, "fit")) return cmd_fit(argc, argv);
    if (!std::strcmp(cmd, "feed")) return cmd_feed(argc, argv);
    if (!std::strcmp(cmd, "watch")) return cmd_watch(argc, argv);
    if (!std::strcmp(cmd, "status")) return cmd_status(argc, argv);
    if (!std::strcmp(cmd, "fillets")) return cmd_fillets(argc, argv);
    if (!std::strcmp(cmd, "image")) return cmd_image(argc, argv);
    if (!std::strcmp(cmd, "lanes")) return cmd_lanes(argc, argv);
    if (!std::strcmp(cmd, "learned")) return cmd_learned(argc, argv);
    if (!std::strcmp(cmd, "bench") || !std::strcmp(cmd, "bench-server") ||
        !std::strcmp(cmd, "bench-gige") || !std::strcmp(cmd, "bench-forward") ||
        !std::strcmp(cmd, "soak"))
      return run_bench_binary(argv);
    if (!std::strcmp(cmd, "audit")) return cmd_audit(argc, argv);
    if (!std::strcmp(cmd, "db")) return cmd_db(argc, argv);
    if (!std::strcmp(cmd, "token")) return cmd_token(argc, argv);
    if (!std::strcmp(cmd, "plc-sim")) return cmd_plc_sim(argc, argv);
    if (!std::strcmp(cmd, "record")) return cmd_record(argc, argv);
    if (!std::strcmp(cmd, "verify")) return cmd_verify(argc, argv);
    if (!std::strcmp(cmd, "fake-lane")) return cmd_fake_lane(argc, argv);
    std::fprintf(stderr, "rangexctl: unknown command '%s'\n\n%s", cmd, kUsage);
    return 2;
  });
}
