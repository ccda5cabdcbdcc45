// The HTTP API's request parameters, checked: a wrong one throws BadRequest naming it and
// what it must be (answered 400). Kept apart from the HTTP library (a query is a multimap
// of name to value, as httplib::Params is) so that the fuzzer drives exactly this code.
#pragma once
#include <cstdint>
#include <map>
#include <set>
#include <stdexcept>
#include <string>

#include "service/verifications.h"
#include "store/store.h"

namespace rangex {

struct BadRequest : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using QueryParams = std::multimap<std::string, std::string>;

// `v`, the value (or one item) of parameter `name`, as an integer within lo..hi.
int64_t parse_int(const char* name, const std::string& v, int64_t lo, int64_t hi);
// Parameter `name` as an integer within lo..hi, `fallback` when absent.
int64_t int_param(const QueryParams& p, const char* name, int64_t fallback, int64_t lo, int64_t hi);
// A decision as the API names it (pass, reject, not_inspected).
const std::string& checked_decision(const char* name, const std::string& d);
// ?lane&decision&from_ns&to_ns&after&limit&newest of /api/fillets and its CSV export.
FilletQuery fillet_query(const QueryParams& p);
// A comma-separated list: of integers (lanes=1,2), of decisions (decisions=reject,pass).
std::set<int> int_set(const QueryParams& p, const char* name);
std::set<std::string> decision_set(const QueryParams& p, const char* name);
// A fillet uid from a path (digits only, as the route matched them) and an image kind.
int64_t parse_uid(const std::string& digits);
const std::string& checked_image_kind(const std::string& kind);
// The JSON body of POST /api/lanes/L/verification: {"piece": NAME, "x_mm": X,
// "tolerance_mm": T, "fillets": N} (the last two optional); the lane is the path's.
VerificationRequest verification_body(const std::string& body);

}  // namespace rangex
