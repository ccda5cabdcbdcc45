#include "eval_steps.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

#include "commands.h"
#include "core/error.h"
#include "core/text_file.h"
#include "offline/acceptance.h"
#include "sim/plant_physics.h"

namespace rangex::cli {

void run_step(const std::string& log, std::vector<std::string> args) {
  std::string line = "rangexctl";
  for (const auto& s : args) line += " " + s;
  std::vector<char*> argv;
  std::string self = "rangexctl";
  argv.push_back(self.data());
  for (auto& s : args) argv.push_back(s.data());
  std::fflush(stdout);
  std::fflush(stderr);
  const int out = dup(1), err = dup(2);
  const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  if (fd < 0) fail(log, ": cannot open");
  const std::string header = "$ " + line + "\n";
  if (write(fd, header.data(), header.size()) != ssize_t(header.size()))
    fail(log, ": write failed");
  dup2(fd, 1), dup2(fd, 2);
  int rc = 0;
  std::string what;
  try {
    const std::string cmd = argv[1];
    const int argc = int(argv.size());
    rc = cmd == "simulate"  ? cmd_simulate(argc, argv.data())
         : cmd == "process" ? cmd_process(argc, argv.data())
         : cmd == "learn"   ? cmd_learn(argc, argv.data())
                            : cmd_calib(argc, argv.data());
  } catch (const std::exception& e) {
    what = e.what();
    rc = 1;
  }
  std::fflush(stdout);
  std::fflush(stderr);
  dup2(out, 1), dup2(err, 2);
  close(out), close(err), close(fd);
  // A solver's failed report (2) is part of the result; anything else stops the variant.
  if (rc != 0 && rc != 2)
    fail(line, " failed", what.empty() ? "" : ": " + what, " (log: ", log, ")");
}

std::string interval(int k, int n) {
  if (n == 0) return "-";
  const Interval w = wilson95(k, n);
  char b[32];
  std::snprintf(b, sizeof b, "%.1f-%.1f", 100 * w.lo, 100 * w.hi);
  return b;
}

void calcified_2mm(const DetectionEval& e, int& found, int& total) {
  found = total = 0;
  for (int s = 1; s < kSizeBins; ++s) found += e.found[s][1], total += e.total[s][1];
}

std::string shape_recall(const std::vector<std::pair<std::string, std::pair<int, int>>>& by_shape,
                         const char* shape) {
  for (const auto& [name, fb] : by_shape)
    if (name == shape) return std::to_string(fb.first) + "/" + std::to_string(fb.second);
  return "-";
}

std::string shape_recall(const DetectionEval& e, const char* shape) {
  return shape_recall(e.by_shape, shape);
}

std::string prefixed(const std::string& text, const std::string& prefix) {
  std::string out;
  size_t at = 0;
  while (at < text.size()) {
    const size_t end = text.find('\n', at);
    const size_t stop = end == std::string::npos ? text.size() : end + 1;
    out += prefix + text.substr(at, stop - at);
    at = stop;
  }
  return out;
}

void run_in_parts(
    const PartRun& o,
    const std::function<void(int, long, const std::string&, const std::string&)>& judged) {
  const std::string rec = (o.dir / o.rec).string();
  for (int part = 0, done = 0; done < o.fillets; ++part) {
    const int n = std::min(o.part, o.fillets - done);
    const long seed = o.seed + 100 * part;
    const std::string out = (o.dir / (o.out + std::to_string(part))).string();
    std::vector<std::string> sim = {"simulate",        "--out",  rec,
                                    "--lanes",         "1",      "--fillets",
                                    std::to_string(n), "--seed", std::to_string(seed),
                                    "--physics",       o.physics};
    if (o.clean) sim.push_back("--clean");
    if (!o.config.empty()) sim.insert(sim.end(), {"--config", o.config});
    run_step(o.log, std::move(sim));
    // The learned configuration in place of the plant's.
    if (!o.learned.empty())
      run_step(o.log, {"process", rec, "--out", out, "--images", "none", "--calibration", o.cal,
                       "--config", o.learned});
    if (judged) judged(part, seed, rec, out);
    if (!o.keep) std::filesystem::remove_all(rec);
    done += n;
  }
}

VariantRun::VariantRun(const std::filesystem::path& file, const std::filesystem::path& d)
    : physics(file.string()), dir(d) {
  const sim::PlantPhysics ph = sim::load_plant_physics(physics);
  name = ph.name, held_out = ph.held_out;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  log = at("log.txt"), cal = at("lane0.yaml");
}

VariantTruth::VariantTruth(const RecordingReader& rec, const LaneConfig& lc) {
  const RecordingInfo& info = rec.info();
  const int lane = info.lanes.at(0);
  const std::string td = rec.lane_dir(lane) + "/truth/";
  fragments = parse_truth_fragments(read_text_file(td + "fragments.csv"), lane);
  fillets = parse_truth_fillets(read_text_file(td + "fillets.csv"), lane);
  thickness = rec.truth_f32(lane, "thickness.f32", size_t(info.xray_pixels));
  edges.thickness = thickness.data(), edges.lines = info.lines, edges.pixels = info.xray_pixels;
  edges.first_pixel_x_mm = lc.xray.first_pixel_x_mm, edges.pitch_mm = lc.xray.pitch_mm;
  edges.step_mm = info.encoder_step_mm, edges.delay_lines = lc.xray.delay_lines;
  edges.source_x_mm = lc.xray.source_x_mm, edges.source_z_mm = lc.xray.source_z_mm;
  edges.detector_z_mm = lc.xray.detector_z_mm;
}

}  // namespace rangex::cli
