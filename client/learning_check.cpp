#include "learning_check.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/recording.h"
#include "core/text_file.h"
#include "eval_steps.h"
#include "offline/detection_eval.h"
#include "offline/named_fillets.h"

namespace rangex::cli {

namespace {

nlohmann::json learn_report(const std::string& out) {
  const std::filesystem::path p = std::filesystem::path(out).replace_extension(".report");
  return nlohmann::json::parse(read_text_file((p / "learn.json").string()));
}

}  // namespace

LearningCheck learn_as_a_plant_would(const std::string& log, const std::string& learn_rec,
                                     const std::string& out,
                                     const std::vector<std::string>& extra) {
  std::vector<std::string> args = {"learn", learn_rec, "--out", out};
  args.insert(args.end(), extra.begin(), extra.end());
  args.push_back("--force");
  run_step(log, args);
  LearningCheck c;
  nlohmann::json report = learn_report(out);
  std::vector<TruthFillet> truth;
  std::string truth_file;
  int lane = 0;
  std::vector<NamedFillet> kept;
  // A fillet kept in can move the model enough to name another: a plant checks that one too.
  // Each round checks only fillets not checked before; bony ones stay out of every round.
  std::vector<std::pair<int, int64_t>> checked;
  for (int round = 0; round < 3; ++round) {
    std::vector<NamedFillet> named;
    for (const auto& l : report.at("lanes"))
      if (l.contains("flagged_fillets"))
        for (const auto& f : l.at("flagged_fillets")) {
          const NamedFillet n{f.at("lane").get<int>(), f.at("fillet").get<int64_t>(),
                              f.at("belt_mm").get<double>()};
          if (std::find(checked.begin(), checked.end(), std::pair{n.lane, n.id}) != checked.end())
            continue;
          checked.push_back({n.lane, n.id});
          named.push_back(n);
        }
    if (named.empty()) break;
    if (truth_file.empty()) {
      const RecordingReader rec(learn_rec);
      lane = rec.info().lanes.at(0);
      truth_file = rec.lane_dir(lane) + "/truth/fillets.csv";
      truth = parse_truth_fillets(read_text_file(truth_file), lane);
    }
    const NamedFilletCheck k = check_named_fillets(named, truth, lane);
    c.named += int(named.size());
    c.kept += int(k.clean.size()), c.bony += int(k.bony.size());
    std::ofstream(log, std::ios::app)
        << "# the fillets it named, checked against " << truth_file << ":\n"
        << k.notes;
    if (k.clean.empty()) break;
    kept.insert(kept.end(), k.clean.begin(), k.clean.end());
    std::vector<std::string> again = args;
    again.insert(again.end() - 1, {"--keep", keep_list(kept)});
    run_step(log, again);
    report = learn_report(out);
  }
  return c;
}

}  // namespace rangex::cli
