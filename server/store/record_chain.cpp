#include "store/record_chain.h"

#include <cstdio>

#include "core/error.h"
#include "store/sha256_hex.h"

namespace rangex {

namespace {
std::string exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
// Strings are length-prefixed, so no separator inside one can forge another field.
void field(std::string& out, const char* name, const std::string& v) {
  out += name;
  out += '=';
  out += std::to_string(v.size());
  out += ':';
  out += v;
  out += '\n';
}
void field(std::string& out, const char* name, int64_t v) {
  field(out, name, std::to_string(v));
}
void field(std::string& out, const char* name, double v) {
  field(out, name, exact(v));
}
}  // namespace

std::string chain_content(const StoredFillet& f) {
  std::string s = "fillet\n";
  field(s, "uid", f.uid);
  field(s, "lane", int64_t(f.lane));
  field(s, "lane_fillet", f.lane_fillet);
  field(s, "first_encoder", f.first_encoder);
  field(s, "rows", int64_t(f.rows));
  field(s, "decision", f.decision);
  field(s, "reason", f.reason);
  field(s, "calibration", f.calibration_id);
  field(s, "decided_ns", f.decided_ns);
  for (const auto& [name, v] : {std::pair<const char*, double>{"beta0", f.beta0},
                                {"beta1", f.beta1},
                                {"beta2", f.beta2},
                                {"resid_mean_dn", f.resid_mean_dn},
                                {"resid_std_dn", f.resid_std_dn},
                                {"belt_y0_mm", f.belt_y0_mm}})
    field(s, name, v);
  field(s, "fragments", int64_t(f.fragments.size()));
  for (const StoredFragment& g : f.fragments) {
    field(s, "kind", g.kind);
    for (double v : {g.x_mm, g.y_mm, g.area_mm2, g.peak_z, g.attenuation_mm2, g.meat_mm})
      field(s, "v", v);
    for (int v : {g.row0, g.row1, g.col0, g.col1}) field(s, "px", int64_t(v));
    // Dual energy's mass joins the chain only where there is one: records of one energy
    // keep the bytes they were chained with.
    if (g.bone_mg != 0) field(s, "bone_mg", g.bone_mg);
  }
  return s;
}

std::string chain_content(int64_t audit_row, const AuditEntry& e) {
  std::string s = "audit\n";
  field(s, "row", audit_row);
  field(s, "ts_ns", e.ts_ns);
  field(s, "who", e.who);
  field(s, "what", e.what);
  field(s, "detail", e.detail);
  return s;
}

std::string chain_hash(const std::string& prev, const std::string& content) {
  return sha256_hex(prev + "\n" + content);
}

}  // namespace rangex
