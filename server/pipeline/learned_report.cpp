#include "pipeline/learned_report.h"

#include <nlohmann/json.hpp>

#include "core/json_text.h"

namespace rangex {

namespace {

nlohmann::json model_json(const GevModel& g) {
  return {{"m0", g.m0},
          {"m_logn", g.m_logn},
          {"m_t", g.m_t},
          {"s0", g.s0},
          {"s_t", g.s_t},
          {"xi", g.xi},
          {"log_n_ref", g.log_n_ref},
          {"t_ref", g.t_ref},
          {"k_logn", g.k_logn}};
}

nlohmann::json cells_json(const std::vector<SensitivityCell>& cells) {
  nlohmann::json out = nlohmann::json::array();
  for (const SensitivityCell& c : cells)
    out.push_back({{"shape", piece_shape_name(c.shape)},
                   {"size_mm", c.size_mm},
                   {"band", c.band},
                   {"injected", c.injected},
                   {"found", c.found}});
  return out;
}

nlohmann::json claims_json(const SensitivityResult& s) {
  nlohmann::json claims = nlohmann::json::array();
  for (const SensitivityClaim& c : s.claims)
    claims.push_back({{"shape", piece_shape_name(c.shape)},
                      {"band", c.band},
                      {"band_mm", {c.band_lo_mm, c.band_hi_mm}},
                      {"size_mm", c.size_mm},
                      {"pod_lower", c.pod_lower}});
  return claims;
}

// What other false-reject targets would buy: per target, the rate its thresholds imply,
// the round and needle thresholds, and the sensitivity.
nlohmann::json tradeoff_json(const std::vector<TradeoffPoint>& points) {
  nlohmann::json out = nlohmann::json::array();
  for (const TradeoffPoint& t : points)
    out.push_back({{"target_frr", t.target_frr},
                   {"implied_frr", t.implied_frr},
                   {"thresholds",
                    {{"round", t.learned.stats[kStatRound].thresholds},
                     {"needle", t.learned.stats[kStatNeedle].thresholds}}},
                   {"summary", t.sensitivity.summary},
                   {"claims_95", claims_json(t.sensitivity)},
                   {"cells", cells_json(t.sensitivity.cells)}});
  return out;
}

}  // namespace

std::string learned_report_json(int lane, const ProductLearning& L, const SensitivityResult& s,
                                const std::vector<TradeoffPoint>& tradeoff) {
  nlohmann::json j = {{"lane", lane},
                      {"ok", L.ok},
                      {"problems", L.problems},
                      {"fillets", L.fillets},
                      {"version", L.learned.version},
                      {"target_frr", L.learned.target_frr},
                      {"confidence", L.learned.confidence},
                      {"band_edges_mm", L.learned.band_edges_mm}};
  auto fillet_json = [](const FlaggedFillet& f) {
    return nlohmann::json{{"lane", f.lane},
                          {"fillet", f.id},
                          {"belt_mm", f.y0_mm},
                          {"statistic", statistic_name(f.stat)},
                          {"band", f.band},
                          {"extreme", f.x},
                          {"log10_probability", f.log10_survival},
                          {"robust_deviations", f.robust_z}};
  };
  for (const FlaggedFillet& f : L.flagged) j["flagged_fillets"].push_back(fillet_json(f));
  // Fillets that stood out as the flagged ones do, kept in because they were checked clean.
  for (const FlaggedFillet& f : L.kept) j["kept_checked_clean"].push_back(fillet_json(f));
  for (int k = 0; k < kStatistics; ++k) {
    const StatisticLearning& st = L.stats[size_t(k)];
    const LearnedStatistic& ls = L.learned.stats[size_t(k)];
    nlohmann::json qq = nlohmann::json::array();
    for (const QQPoint& q : st.qq) qq.push_back({q.expected, q.observed});
    j["statistics"][statistic_name(k)] = {{"samples", st.samples},
                                          {"budget", st.budget},
                                          {"point_thresholds", st.point_thresholds},
                                          {"thresholds", ls.thresholds},
                                          {"implied_frr", st.implied_frr},
                                          {"band_fraction", ls.band_fraction},
                                          {"band_pixels", ls.band_pixels},
                                          {"band_thickness_mm", ls.band_thickness_mm},
                                          {"model", model_json(ls.model)},
                                          {"converged", st.fit.converged},
                                          {"ks_d", st.ks_d},
                                          {"ks_p", st.ks_p},
                                          {"ks_samples", st.ks_samples},
                                          {"tail_from", st.fit.tail_from},
                                          {"top_above", st.top_above},
                                          {"top_p", st.top_p},
                                          {"qq_gumbel", qq}};
  }
  const nlohmann::json cells = cells_json(s.cells);
  const nlohmann::json claims = claims_json(s);
  nlohmann::json stated = nlohmann::json::array();
  for (const StatedClaim& c : s.stated)
    stated.push_back({{"shape", piece_shape_name(c.shape)},
                      {"size_mm", c.size_mm},
                      {"bands", {c.first_band, c.last_band}},
                      {"up_to_mm", c.up_to_mm}});
  j["sensitivity"] = {
      {"cells", cells},
      {"claims_95", claims},
      {"summary", s.summary},
      {"stated", stated},
      {"inspections", s.inspections},
      {"measured_on",
       s.inspections > 0 ? "the learning fillets, with the learned thresholds" : "not measured"},
      {"rate", s.rate},
      {"claim_confidence", s.claim_confidence},
      {"material",
       {{"excess_ratio", s.material.excess_ratio}, {"excess_per_mm", s.material.excess_per_mm}}},
      {"claim_rule",
       "found at >= rate at the size and every larger one, and the band's "
       "hit/miss detection curve (logit POD linear in ln size, Firth's "
       "penalised likelihood) has its one-sided claim_confidence lower bound "
       ">= rate there"}};
  if (!tradeoff.empty()) j["tradeoff"] = tradeoff_json(tradeoff);
  return json_dump(j);
}

std::string claim_checks_json(const std::string& recording, int fillets,
                              const std::vector<ClaimCheck>& checks,
                              const std::vector<StatedCheck>& stated,
                              const std::vector<SensitivityCell>& cells) {
  nlohmann::json list = nlohmann::json::array();
  int held = 0, contradicted = 0;
  for (const ClaimCheck& k : checks) {
    held += k.held, contradicted += k.contradicted;
    list.push_back({{"shape", piece_shape_name(k.claim.shape)},
                    {"band", k.claim.band},
                    {"size_mm", k.claim.size_mm},
                    {"injected", k.injected},
                    {"found", k.found},
                    {"held", k.held},
                    {"p_at_rate", k.p_at_rate},
                    {"contradicted", k.contradicted},
                    {"text", claim_check_text(k)}});
  }
  nlohmann::json sentences = nlohmann::json::array();
  int stated_held = 0, stated_contradicted = 0;
  for (const StatedCheck& k : stated) {
    stated_held += k.held, stated_contradicted += k.contradicted;
    sentences.push_back({{"sentence", k.claim.text},
                         {"shape", piece_shape_name(k.claim.shape)},
                         {"size_mm", k.claim.size_mm},
                         {"up_to_mm", k.claim.up_to_mm},
                         {"injected", k.injected},
                         {"found", k.found},
                         {"held", k.held},
                         {"p_at_rate", k.p_at_rate},
                         {"contradicted", k.contradicted}});
  }
  const nlohmann::json j = {{"recording", recording},
                            {"fillets", fillets},
                            {"claims", checks.size()},
                            {"held", held},
                            {"contradicted", contradicted},
                            {"checks", list},
                            {"stated", stated.size()},
                            {"stated_held", stated_held},
                            {"stated_contradicted", stated_contradicted},
                            {"stated_checks", sentences},
                            {"cells", cells_json(cells)}};
  return json_dump(j);
}

LearnedReportStatus check_learned_report(const std::string& report, int lane) {
  LearnedReportStatus s;
  if (report.empty()) {
    s.why = "the learned settings have no report";
    return s;
  }
  s.present = true;
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(report);
  } catch (const std::exception& e) {
    s.why = std::string("the report cannot be read: ") + e.what();
    return s;
  }
  const nlohmann::json* entry = nullptr;
  if (j.is_object() && j.contains("lanes") && j["lanes"].is_array()) {
    for (const auto& l : j["lanes"])
      if (l.is_object() && l.value("lane", -1) == lane) entry = &l;
  } else if (j.is_object() && j.contains("ok")) {
    entry = &j;
  }
  if (!entry) {
    s.why = "the report holds nothing for lane " + std::to_string(lane);
    return s;
  }
  if (!entry->contains("ok") || !(*entry)["ok"].is_boolean()) {
    s.why = "the report cannot be read: no \"ok\"";
    return s;
  }
  s.passed = (*entry)["ok"].get<bool>();
  auto ids = [&](const char* key, std::vector<int64_t>& out) {
    if (!entry->contains(key) || !(*entry)[key].is_array()) return;
    for (const auto& f : (*entry)[key])
      if (f.is_object() && f.value("lane", lane) == lane && f.contains("fillet") &&
          f["fillet"].is_number_integer())
        out.push_back(f["fillet"].get<int64_t>());
  };
  ids("flagged_fillets", s.flagged);
  ids("kept_checked_clean", s.kept);
  if (!s.passed) {
    s.why = "the learning failed";
    if (entry->contains("problems") && (*entry)["problems"].is_array())
      for (const auto& p : (*entry)["problems"])
        if (p.is_string()) s.why += "; " + p.get<std::string>();
  }
  return s;
}

}  // namespace rangex
