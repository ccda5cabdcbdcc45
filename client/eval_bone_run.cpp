#include "eval_bone_run.h"

#include <algorithm>
#include <filesystem>

#include "eval_steps.h"
#include "offline/fillet_records.h"

namespace fs = std::filesystem;

namespace rangex::cli {

std::vector<BonePart> run_bone_parts(
    const std::string& dir, const std::string& log, const std::string& physics,
    const std::string& cal, const std::string& learned, const LaneConfig& lane,
    const BoneRunOptions& o,
    const std::function<void(DetectionEval&, const RecordingReader&)>& margins) {
  std::vector<BonePart> parts;
  const std::string rec_dir = (fs::path(dir) / "bone_rec").string();
  for (int part = 0, done = 0; done < o.fillets; ++part) {
    const int n = std::min(o.part, o.fillets - done);
    BonePart& p = parts.emplace_back();
    p.seed = o.seed + 100 * part;
    const std::string out = (fs::path(dir) / ("out_bones" + std::to_string(part))).string();
    run_step(log, {"simulate", "--out", rec_dir, "--lanes", "1", "--fillets", std::to_string(n),
                   "--seed", std::to_string(p.seed), "--physics", physics});
    // The learned configuration in place of the plant's (as the learned plant run).
    run_step(log, {"process", rec_dir, "--out", out, "--images", "none", "--calibration", cal,
                   "--config", learned});
    {
      const RecordingReader rec(rec_dir);
      const VariantTruth vt(rec, lane);
      const int l = rec.info().lanes.at(0);
      add_lane(p.eval, vt.fragments, vt.fillets,
               read_records((fs::path(out) / ("lane" + std::to_string(l))).string(), ""),
               &vt.edges);
      finish(p.eval);
      if (!p.eval.missed.empty()) margins(p.eval, rec);
    }
    if (!o.keep) fs::remove_all(rec_dir);
    done += n;
  }
  return parts;
}

BoneRunTotals pooled(const std::vector<BonePart>& parts) {
  BoneRunTotals t;
  for (const BonePart& p : parts) {
    int k = 0, n = 0;
    calcified_2mm(p.eval, k, n);
    t.found += k, t.present += n;
    t.clean_rejected += p.eval.clean_rejected, t.clean += p.eval.clean_fillets;
    t.false_fragments += p.eval.false_fragments, t.fillets += p.eval.fillets;
    for (const auto& [shape, fp] : p.eval.by_shape) {
      auto it = std::find_if(t.by_shape.begin(), t.by_shape.end(),
                             [&](const auto& s) { return s.first == shape; });
      if (it == t.by_shape.end()) it = t.by_shape.insert(t.by_shape.end(), {shape, {0, 0}});
      it->second.first += fp.first, it->second.second += fp.second;
    }
  }
  return t;
}

std::string bone_run_missed_lines(const std::vector<BonePart>& parts) {
  std::string out;
  for (const BonePart& p : parts) {
    const std::string lines = missed_lines(p.eval);
    size_t at = 0;
    while (at < lines.size()) {
      const size_t end = lines.find('\n', at);
      const size_t stop = end == std::string::npos ? lines.size() : end + 1;
      out += "seed " + std::to_string(p.seed) + " " + lines.substr(at, stop - at);
      at = stop;
    }
  }
  return out;
}

}  // namespace rangex::cli
