#include "learning_check.h"

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

bool report_ok(const nlohmann::json& j) {
  bool ok = true;
  for (const auto& l : j.at("lanes")) ok = ok && l.at("ok").get<bool>();
  return ok;
}

}  // namespace

LearningCheck learn_as_a_plant_would(const std::string& log, const std::string& learn_rec,
                                     const std::string& out,
                                     const std::vector<std::string>& extra) {
  std::vector<std::string> args = {"learn", learn_rec, "--out", out};
  args.insert(args.end(), extra.begin(), extra.end());
  args.push_back("--force");
  run_step(log, args);
  const nlohmann::json first = learn_report(out);
  std::vector<NamedFillet> named;
  for (const auto& l : first.at("lanes"))
    if (l.contains("flagged_fillets"))
      for (const auto& f : l.at("flagged_fillets"))
        named.push_back({f.at("lane").get<int>(), f.at("fillet").get<int64_t>(),
                         f.at("belt_mm").get<double>()});
  LearningCheck c;
  c.named = int(named.size());
  c.ok = report_ok(first);
  if (named.empty()) return c;
  const RecordingReader rec(learn_rec);
  const int lane = rec.info().lanes.at(0);
  const std::string truth = rec.lane_dir(lane) + "/truth/fillets.csv";
  const NamedFilletCheck k =
      check_named_fillets(named, parse_truth_fillets(read_text_file(truth), lane), lane);
  c.kept = int(k.clean.size()), c.bony = int(k.bony.size());
  std::ofstream(log, std::ios::app) << "# the fillets it named, checked against " << truth << ":\n"
                                    << k.notes;
  if (k.clean.empty()) return c;
  args.insert(args.end() - 1, {"--keep", keep_list(k.clean)});
  run_step(log, args);
  c.ok = report_ok(learn_report(out));
  return c;
}

}  // namespace rangex::cli
