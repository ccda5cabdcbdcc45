#include "eval_bone_run.h"

#include <algorithm>
#include <filesystem>

#include "offline/fillet_records.h"

namespace fs = std::filesystem;

namespace rangex::cli {

std::vector<BonePart> run_bone_parts(
    PartRun o, const LaneConfig& lane,
    const std::function<void(DetectionEval&, const RecordingReader&)>& margins) {
  o.clean = false, o.rec = "bone_rec", o.out = "out_bones";
  std::vector<BonePart> parts;
  run_in_parts(o, [&](int, long seed, const std::string& rec_dir, const std::string& out) {
    BonePart& p = parts.emplace_back();
    p.seed = seed;
    const RecordingReader rec(rec_dir);
    const VariantTruth vt(rec, lane);
    const int l = rec.info().lanes.at(0);
    add_lane(p.eval, vt.fragments, vt.fillets,
             read_records((fs::path(out) / ("lane" + std::to_string(l))).string(), ""), &vt.edges);
    finish(p.eval);
    margins(p.eval, rec);
  });
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
    t.calcified_fillets += p.eval.calcified_fillets;
    t.calcified_passed += p.eval.calcified_passed;
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
  for (const BonePart& p : parts)
    out += prefixed(missed_lines(p.eval), "seed " + std::to_string(p.seed) + " ");
  return out;
}

}  // namespace rangex::cli
