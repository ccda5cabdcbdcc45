#include "eval_claims.h"

#include <cstdio>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/json_text.h"
#include "core/text_file.h"

namespace rangex::cli {

ReportClaims report_claims(const std::string& learn_json, int lane) {
  const auto j = nlohmann::json::parse(read_text_file(learn_json));
  for (const auto& l : j.at("lanes")) {
    if (l.at("lane").get<int>() != lane) continue;
    const auto& s = l.at("sensitivity");
    if (!s.contains("material"))
      fail(learn_json, ": lane ", lane, "'s sensitivity has no material (written before it was)");
    ReportClaims rc;
    rc.material.excess_ratio = s["material"].at("excess_ratio").get<double>();
    rc.material.excess_per_mm = s["material"].at("excess_per_mm").get<double>();
    for (const auto& c : s.at("claims_95"))
      if (c.at("shape").get<std::string>() == "sphere")
        rc.spheres.push_back({c.at("band_mm").at(0).get<double>(),
                              c.at("band_mm").at(1).get<double>(), c.at("size_mm").get<double>()});
    return rc;
  }
  fail(learn_json, ": no lane ", lane);
}

FragmentClaims claims_on_fragments(const ReportClaims& rc, const DetectionEval& plant,
                                   long plant_seed, const std::vector<BonePart>& bones) {
  FragmentClaims out;
  auto add = [&](const DetectionEval& e, long seed) {
    const ClaimCoverage c = claim_coverage(e.judged, rc.spheres, rc.material);
    ClaimCoverage& p = out.pooled;
    p.found += c.found, p.covered += c.covered, p.unknown += c.unknown, p.weighed += c.weighed;
    p.dense_found += c.dense_found, p.dense_covered += c.dense_covered;
    p.missed.insert(p.missed.end(), c.missed.begin(), c.missed.end());
    out.missed_seed.insert(out.missed_seed.end(), c.missed.size(), seed);
  };
  add(plant, plant_seed);
  for (const BonePart& b : bones) add(b.eval, b.seed);
  return out;
}

std::string claims_text(const std::string& name, const FragmentClaims& fc) {
  const ClaimCoverage& c = fc.pooled;
  char b[400];
  std::snprintf(b, sizeof b,
                "%s: %d/%d found of the compact fragments its sphere claims cover (holding at "
                "least the claimed sphere's bone where they lie); of those at least as dense as "
                "the test piece %d/%d%s\n",
                name.c_str(), c.found, c.covered, c.dense_found, c.dense_covered,
                c.unknown ? "; some fragments' truth cannot weigh their bone" : "");
  std::string out = b;
  for (size_t k = 0; k < c.missed.size(); ++k) {
    const JudgedFragment& f = c.missed[k].fragment;
    std::snprintf(b, sizeof b,
                  "  missed: seed %ld fillet %d, %.1f mm, the bone of a %.2f mm sphere under "
                  "%.1f mm of meat, where %.1f mm is claimed\n",
                  fc.missed_seed[k], f.fillet, f.size_mm, c.missed[k].sphere_mm, f.meat_mm,
                  c.missed[k].claim_mm);
    out += b;
  }
  return out;
}

std::string claims_json(const FragmentClaims& fc) {
  const ClaimCoverage& c = fc.pooled;
  nlohmann::json missed = nlohmann::json::array();
  for (size_t k = 0; k < c.missed.size(); ++k) {
    const JudgedFragment& f = c.missed[k].fragment;
    missed.push_back({{"seed", fc.missed_seed[k]},
                      {"fillet", f.fillet},
                      {"size_mm", f.size_mm},
                      {"calcification", f.calcification},
                      {"meat_mm", f.meat_mm},
                      {"sphere_mm", c.missed[k].sphere_mm},
                      {"claimed_mm", c.missed[k].claim_mm}});
  }
  return json_dump({{"found", c.found},
                    {"covered", c.covered},
                    {"dense_found", c.dense_found},
                    {"dense_covered", c.dense_covered},
                    {"weighed", c.weighed},
                    {"unknown", c.unknown},
                    {"missed", missed}});
}

}  // namespace rangex::cli
