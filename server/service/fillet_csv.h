// Stored fillets as CSV, one row per fillet, for an audit (the dashboard's records export):
// what was decided, when, by which calibration, with the fit and every fragment found.
#pragma once
#include <string>
#include <vector>

#include "store/store.h"

namespace rangex {

std::string fillet_csv_header();
std::string fillet_csv_row(const StoredFillet& f);

}  // namespace rangex
