#include "backends/verify.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace rangex {

namespace {

template <class A, class B>
std::optional<Mismatch> first_off(const char* what, const A& got, const B& want, double tol,
                                  int lines) {
  if (got.size() != want.size())
    return Mismatch{join(what, " count"), 0, 0, double(got.size()), double(want.size())};
  const size_t per_line = lines > 0 ? std::max<size_t>(1, got.size() / size_t(lines)) : 1;
  for (size_t i = 0; i < got.size(); ++i) {
    const double g = got[i], w = want[i];
    if (std::isnan(g) && std::isnan(w)) continue;
    if (!(std::fabs(g - w) <= tol)) return Mismatch{what, i, i / per_line, g, w};
  }
  return std::nullopt;
}

}  // namespace

std::string Mismatch::describe() const {
  return join(what, " item ", index, ": ", got, " against the CPU's ", want);
}

std::optional<Mismatch> compare_line_results(const LineResults& got, const LineResults& want,
                                             int lines) {
  const StripeOutput &gs = got.stripes, &ws = want.stripes;
  if (auto m = first_off("stripe valid", gs.valid, ws.valid, 0, lines)) return m;
  if (auto m = first_off("stripe peak", gs.peak, ws.peak, 0, lines)) return m;
  if (auto m = first_off("stripe width", gs.width, ws.width, 0, lines)) return m;
  if (auto m = first_off("stripe row", gs.row, ws.row, Tolerance::kRowPx, lines)) return m;
  if (auto m = first_off("thickness valid", got.thickness_valid, want.thickness_valid, 0, lines))
    return m;
  return first_off("thickness", got.thickness, want.thickness, Tolerance::kThicknessMm, lines);
}

}  // namespace rangex
