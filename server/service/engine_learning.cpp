// Learned inspection settings in the engine: versions uploaded, listed and
// activated like calibrations, and live learning from a lane's next fillets
// (ControlService.LearnProduct). The learning itself is pipeline/lane_learning.h; its
// report and gate are pipeline/learned_report.h.
#include <algorithm>
#include <chrono>
#include <map>

#include "core/error.h"
#include "core/log.h"
#include "core/plant_config.h"
#include "core/size_limits.h"
#include "pipeline/lane_learning.h"
#include "pipeline/learned_report.h"
#include "service/engine.h"

namespace rangex {

// What a live learning run has of a lane's next fillets: their images when the worker cuts
// them (a copy; the inspection takes the original), their extremes once inspected.
struct ProductCollector {
  int want = 40;
  std::mutex mu;
  std::condition_variable cv;
  std::map<int64_t, FilletImage> cut;  // by the lane's fillet id, waiting for a decision
  LearningSet set;
  bool done() const { return int(set.size()) >= want; }
};

std::shared_ptr<ProductCollector> Engine::collector_of(Lane& l) {
  std::lock_guard<std::mutex> lock(learn_mu_);
  return l.collector;
}

void Engine::collect_image(Lane& l, const FilletImage& img) {
  const auto c = collector_of(l);
  if (!c) return;
  std::lock_guard<std::mutex> lock(c->mu);
  if (int(c->set.size() + c->cut.size()) < c->want) c->cut.emplace(img.id, img);
}

void Engine::collect_result(Lane& l, const FilletResult& r) {
  const auto c = collector_of(l);
  if (!c) return;
  std::lock_guard<std::mutex> lock(c->mu);
  const auto it = c->cut.find(r.id);
  if (it == c->cut.end()) return;
  // Fillets left out are counted to the end; the set takes no more than it wants.
  if (!LearningSet::teaches(r) || !c->done()) c->set.add(r, std::move(it->second));
  c->cut.erase(it);
  if (c->done()) c->cv.notify_all();
}

StoredSetting Engine::upload_learned(int id, const std::string& vid, const std::string& yaml,
                                     const std::string& report, const std::string& who) {
  lane(id);  // NOT_FOUND for an unknown lane
  check_name("learned settings' id", vid);
  check_size("learned settings '" + vid + "'", yaml.size(), kMaxLearnedBytes);
  check_size("learned settings '" + vid + "' report", report.size(), kMaxReportBytes);
  // Parsed now: a malformed section is refused at upload, naming the key.
  const LearnedDetection L = parse_learned_detection(yaml, "learned settings '" + vid + "'");
  const LearnedReportStatus rs = check_learned_report(report, id);
  if (rs.present && !rs.passed && rs.why.rfind("the report cannot be read", 0) == 0)
    fail("learned settings '", vid, "': ", rs.why);
  StoredSetting s{id, vid, yaml, now_ns(), false, report};
  store_.add_setting(SettingKind::kLearned, s);
  store_.audit(who, "learned.upload",
               "lane " + std::to_string(id) + " id " + vid + " learned from " +
                   std::to_string(L.fillets) + " fillets, report " +
                   (rs.passed    ? "passed"
                    : rs.present ? "failed"
                                 : "missing"));
  return s;
}

bool Engine::activate_learned(int id, const std::string& vid, const std::string& who, bool force) {
  Lane& l = lane(id);
  const auto s = store_.setting(SettingKind::kLearned, id, vid);
  if (!s) fail_not_found("lane ", id, " has no learned settings '", vid, "'");
  const LearnedReportStatus rs = check_learned_report(s->report, id);
  if (!rs.passed && !force)
    throw FailedPrecondition(join("learned settings '", vid, "' of lane ", id,
                                  " are not activated: ", rs.why,
                                  " (force the activation to override; it is audited)"));
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    LaneConfig next = l.pending ? *l.pending : l.config;
    apply_learned(next, *s);
    l.pending = std::move(next);
  }
  store_.set_active_setting(SettingKind::kLearned, id, vid);
  if (rs.passed)
    store_.audit(who, "learned.activate", "lane " + std::to_string(id) + " id " + vid);
  else
    store_.audit(who, "learned.activate.forced",
                 "lane " + std::to_string(id) + " id " + vid + ": " + rs.why);
  return true;
}

void Engine::apply_learned(LaneConfig& lane, const StoredSetting& s) {
  LearnedDetection L = parse_learned_detection(s.yaml, "learned settings " + s.id);
  L.version = s.id;  // the name it is stored under is the one the lane shows
  lane.inspection.false_reject_target = L.target_frr;
  lane.inspection.learned = std::move(L);
}

std::vector<StoredSetting> Engine::learned_settings(int id) {
  if (id >= 0) lane(id);  // NOT_FOUND for an unknown lane
  return store_.settings(SettingKind::kLearned, id);
}

// A lane's last live learning run: its fillets and the settings they were learned with, for
// a re-learning that keeps fillets an operator checked clean. The set is immutable; the
// versions learned from it grow, and the set is dropped when too large to keep, under
// learn_mu_ (before it is published).
struct KeptLearning {
  LearningSet set;
  InspectionParams inspection;
  LearnOptions lo;
  std::string why_not_kept;           // the images were too large to keep: set is empty
  std::vector<std::string> versions;  // stored from these fillets, first the run's own
};

namespace {

size_t image_bytes(const LearningSet& set) {
  size_t n = 0;
  for (const FilletImage& f : set.images)
    n += f.xray.size() * 2 + f.xray_high.size() * 2 + f.thickness.size() * 4 + f.mask.size();
  return n;
}

// In an error the first 20 and how many in all (it names what is wrong without growing with
// it); in the audit every one (at most 1000).
std::string id_list(const std::vector<int64_t>& ids, size_t most = 20) {
  std::string s;
  for (size_t i = 0; i < ids.size() && i < most; ++i)
    s += (s.empty() ? "" : ", ") + std::to_string(ids[i]);
  if (ids.size() > most) s += ", ... (" + std::to_string(ids.size()) + " in all)";
  return s;
}

// Refuses a request that names a bad value, before any fillet is collected.
void check_learn_request(const Engine::LearnRequest& req) {
  const bool relearn = !req.relearn_from.empty();
  if (req.min_fillets < 0 || req.min_fillets > 10000)
    fail("min_fillets must be within 0..10000 (0: 30, or the run's; got ", req.min_fillets, ")");
  if (!relearn && (req.fillets < 1 || req.fillets > 10000))
    fail("fillets must be within 1..10000 (got ", req.fillets, ")");
  if (!(req.target_frr >= 0 && req.target_frr < 0.5))
    fail("target_frr must be in (0, 0.5) (0: the lane's false_reject_target)");
  if (!(req.confidence >= 0.5 && req.confidence < 1)) fail("confidence must be in [0.5, 1)");
  if (!(req.timeout_s > 0 && req.timeout_s <= 86400)) fail("timeout_s must be within (0, 86400]");
  if (req.tradeoff.size() > 8) fail("tradeoff_targets: at most 8 (got ", req.tradeoff.size(), ")");
  for (double t : req.tradeoff)
    if (!(t > 0 && t < 0.5)) fail("tradeoff_targets must be in (0, 0.5) (got ", t, ")");
  // The next fillets' ids are not known yet: an operator can only have checked fillets a
  // run has named.
  if (!req.keep.empty() && !relearn)
    fail(
        "keep_fillets names fillets of an earlier learning run: give relearn_from, the id of "
        "the version that run stored");
  if (req.keep.size() > 1000) fail("keep_fillets: at most 1000 (got ", req.keep.size(), ")");
}

// A new run learns with the lane's inspection settings.
void learn_with_lane_settings(KeptLearning& run, const LaneConfig& lc,
                              const Engine::LearnRequest& req) {
  run.inspection = lc.inspection;
  // The run's own target and confidence: a re-learning keeps them unless it asks for others.
  run.lo.target_frr = req.target_frr > 0 ? req.target_frr : lc.inspection.false_reject_target;
  run.lo.confidence = req.confidence;
  if (req.min_fillets > 0) run.lo.min_fillets = req.min_fillets;  // else LearnOptions' 30
  // The lane ran with its own settings; extremes come in its bands.
  if (lc.inspection.learned.active()) {
    run.lo.band_edges_mm = lc.inspection.learned.band_edges_mm;
    run.lo.spread_by_thickness = lc.inspection.learned.spread_by_thickness;
    run.lo.rim_walls = lc.inspection.learned.rim_walls;
  } else {
    run.lo.spread_by_thickness = lc.inspection.spread_by_thickness;
    run.lo.rim_walls = lc.inspection.rim_walls;
  }
}

}  // namespace

StoredSetting Engine::learn_product(int id, const LearnRequest& req, const std::string& who) {
  Lane& l = lane(id);
  const bool relearn = !req.relearn_from.empty();
  check_learn_request(req);
  const std::string vid = req.id.empty() ? learning_version_name() : req.id;
  check_name("learned settings' id", vid);
  if (store_.setting(SettingKind::kLearned, id, vid))
    fail_exists("lane ", id, " already has learned settings '", vid, "' (versions are immutable)");

  std::shared_ptr<KeptLearning> run;
  if (relearn) {
    std::string refused;
    {
      std::lock_guard<std::mutex> lock(learn_mu_);
      run = l.last_learning;
      if (!run)
        refused = "it keeps no live learning run's fillets (none since the server started)";
      else if (std::find(run->versions.begin(), run->versions.end(), req.relearn_from) ==
               run->versions.end())
        refused = "the fillets it keeps are those of '" + run->versions.front() +
                  "'; a lane keeps its last live learning run's fillets only";
      else
        refused = run->why_not_kept;
    }
    if (!refused.empty())
      throw FailedPrecondition(
          join("lane ", id, " cannot learn again from '", req.relearn_from, "': ", refused));
    std::vector<int64_t> absent;
    for (int64_t k : req.keep)
      if (std::none_of(run->set.fillets.begin(), run->set.fillets.end(),
                       [&](const LearningFillet& f) { return f.id == k; }))
        absent.push_back(k);
    if (!absent.empty()) {
      std::vector<int64_t> held;
      for (const LearningFillet& f : run->set.fillets) held.push_back(f.id);
      fail("keep_fillets: lane ", id, "'s learning run '", req.relearn_from, "' holds no fillet ",
           id_list(absent), " (it holds fillets ", id_list(held), ")");
    }
  } else {
    run = std::make_shared<KeptLearning>();
    LearningSet set = collect_fillets(l, id, vid, req, who);
    LaneConfig lc;
    {
      std::lock_guard<std::mutex> lock(ctl_mu_);
      lc = l.config;
    }
    learn_with_lane_settings(*run, lc, req);
    run->set = std::move(set);
  }

  LearnOptions lo = run->lo;
  if (req.target_frr > 0) lo.target_frr = req.target_frr;
  if (req.min_fillets > 0) lo.min_fillets = req.min_fillets;
  for (int64_t k : req.keep) lo.checked_clean.push_back({id, k});
  std::string on = "lane " + std::to_string(id) + " live, " + std::to_string(run->set.size()) +
                   " fillets (" + std::to_string(run->set.not_inspected) +
                   " not inspected left out)";
  if (relearn) on += ", learned again from '" + req.relearn_from + "'";
  if (!req.keep.empty()) on += ", fillets " + id_list(req.keep) + " checked clean";
  // With what other false-reject targets would buy, on the same fillets and test pieces.
  const LaneLearning learned =
      learn_lane(run->set, run->inspection, lo, SensitivityOptions{}, vid, on, {}, req.tradeoff);
  const ProductLearning& L = learned.learning;
  const std::string report = learned_report_json(id, L, learned.sensitivity, learned.tradeoff);
  StoredSetting s{id, vid, learned_detection_yaml(L.learned), now_ns(), false, report};
  // What is stored must read back, as an upload must: a version that does not would only
  // fail at its activation.
  parse_learned_detection(s.yaml, "learned settings '" + vid + "' of lane " + std::to_string(id));
  store_.add_setting(SettingKind::kLearned, s);
  store_.audit(
      who, "learned.learn",
      "lane " + std::to_string(id) + " id " + vid + " from " + std::to_string(L.fillets) +
          " fillets" + (relearn ? " of " + req.relearn_from : std::string()) +
          (req.keep.empty() ? std::string()
                            : ", kept " + id_list(req.keep, req.keep.size()) + " checked clean") +
          ", report " + (L.ok ? "passed" : "failed"));
  {
    std::lock_guard<std::mutex> lock(learn_mu_);
    run->versions.push_back(vid);
    if (!relearn) {
      const size_t bytes = image_bytes(run->set);
      if (bytes > kMaxKeptLearningBytes) {
        run->why_not_kept =
            join("its ", run->set.size(), " fillets' images (", bytes >> 20,
                 " MiB) were more than the ", kMaxKeptLearningBytes >> 20, " MiB a lane keeps");
        run->set = {};
        log::info("learning_not_kept", "lane {}: '{}' not kept for a re-learning: {}", id, vid,
                  run->why_not_kept);
      } else {
        log::info("learning_kept",
                  "lane {} keeps the {} fillets of '{}' ({:.1f} MiB) for a re-learning", id,
                  run->set.size(), vid, double(bytes) / (1 << 20));
      }
      l.last_learning = run;
    }
  }
  return s;
}

LearningSet Engine::collect_fillets(Lane& l, int id, const std::string& vid,
                                    const LearnRequest& req, const std::string& who) {
  auto c = std::make_shared<ProductCollector>();
  c->want = req.fillets;
  {
    std::lock_guard<std::mutex> lock(learn_mu_);
    if (l.collector) throw FailedPrecondition(join("lane ", id, " is already learning"));
    l.collector = c;
  }
  store_.audit(who, "learned.learn.start",
               "lane " + std::to_string(id) + " id " + vid + " over the next " +
                   std::to_string(req.fillets) + " fillets");
  // Waits a fifth of a second at a time: the stop flag is mu_'s, which is not taken under
  // the collector's lock (engine locks never nest).
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(req.timeout_s);
  bool stop = false;
  while (!stop && std::chrono::steady_clock::now() < deadline) {
    {
      std::unique_lock<std::mutex> lock(c->mu);
      if (c->cv.wait_for(lock, std::chrono::milliseconds(200), [&] { return c->done(); })) break;
    }
    std::lock_guard<std::mutex> lock(mu_);
    stop = stopping_;
  }
  {
    std::lock_guard<std::mutex> lock(learn_mu_);
    l.collector.reset();
  }
  // The collector is this thread's alone now.
  if (!c->done())
    fail("lane ", id, ": only ", c->set.size(), " of ", req.fillets,
         " fillets were inspected within ", req.timeout_s, " s",
         stop ? " (the server is stopping)" : "", "; nothing was learned");
  return std::move(c->set);
}

}  // namespace rangex
