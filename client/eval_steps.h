// What eval-matrix's runs share: rangexctl's own commands run in this process with their
// output in a log, and the figures' intervals.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "core/plant_config.h"
#include "core/recording.h"
#include "offline/detection_eval.h"

namespace rangex::cli {

// Runs `rangexctl ARGS...` (simulate, process, learn, calib) in this process with its output
// going to `log`. A solver's failed report (exit 2) is part of the result; anything else
// throws, naming the log.
void run_step(const std::string& log, std::vector<std::string> args);

// Wilson's 95 % interval of k in n, in %, as "lo-hi" ("-" when n is 0).
std::string interval(int k, int n);

// Calcified fragments >= 2 mm: found and present.
void calcified_2mm(const DetectionEval& e, int& found, int& total);

// "found/present" of calcified fragments >= 2 mm of one shape, "-" when none; of an
// evaluation, or of shapes pooled (a bone run's).
std::string shape_recall(const std::vector<std::pair<std::string, std::pair<int, int>>>& by_shape,
                         const char* shape);
std::string shape_recall(const DetectionEval& e, const char* shape);

// A simulated recording's truth of its first lane: its fragments and fillets, and the true
// thickness with the lane's geometry (how far a detection lies from the meat's edge).
struct VariantTruth {
  VariantTruth(const RecordingReader& rec, const LaneConfig& lane);
  VariantTruth(const VariantTruth&) = delete;
  std::vector<TruthFragment> fragments;
  std::vector<TruthFillet> fillets;
  std::vector<float> thickness;
  EdgeMap edges;
};

// A variant's run: its physics file and folder (emptied), the log every step writes, the
// lane calibration the steps build.
struct VariantRun {
  VariantRun(const std::filesystem::path& physics_file, const std::filesystem::path& dir);
  std::string at(const std::string& name) const { return (dir / name).string(); }
  std::string name, physics, log, cal;
  bool held_out = false;
  std::filesystem::path dir;
};

// Each line of `text` with `prefix` before it.
std::string prefixed(const std::string& text, const std::string& prefix);

// More fillets of a variant inspected with its learned thresholds, in parts: part k simulates
// min(part, what is left) fillets of seed + 100 k (no bone when `clean`) into dir/rec, and
// `process`es them with `learned` and `cal` into dir/out + k (when `learned` is empty,
// `judged` processes them itself). Each scan goes once `judged` (may be empty) has seen it,
// unless `keep`: a scan is about 130 MB a fillet.
struct PartRun {
  std::filesystem::path dir;
  std::string log, physics, cal, learned;
  std::string config;  // the plant configuration the simulator reads ("" : the default)
  std::string rec, out;
  int fillets = 0, part = 60;
  long seed = 0;
  bool clean = true, keep = false;
};
void run_in_parts(const PartRun& o,
                  const std::function<void(int part, long seed, const std::string& rec,
                                           const std::string& out)>& judged);

struct DualEnergyMatrixOptions {
  int fillets = 60;
  long seed = 11;
  int learn_fillets = 40, check_fillets = 20, frr_fillets = 0;
  int bone_fillets = 0, part = 60;  // the bone run: more bony fillets, each method's thresholds
  bool keep = false;
};

// eval-matrix --dual-energy (client/eval_dual_energy.cpp): the variants in `files`, each
// inspected by one energy, dual energy without and with the laser, both with the laser, and
// X-ray only.
int run_dual_energy_matrix(const std::vector<std::filesystem::path>& files,
                           const std::filesystem::path& out, const std::string& config,
                           const PlantConfig& plant, const DualEnergyMatrixOptions& mo);

}  // namespace rangex::cli
