#include "rangex/v1/decision_names.h"

namespace rangex {

namespace {
struct Named {
  const char* name;
  v1::Decision value;
};
constexpr Named kDecisions[] = {{"pass", v1::DECISION_PASS},
                                {"reject", v1::DECISION_REJECT},
                                {"not_inspected", v1::DECISION_NOT_INSPECTED}};
}  // namespace

v1::Decision decision_from_name(std::string_view name) {
  for (const Named& d : kDecisions)
    if (name == d.name) return d.value;
  return v1::DECISION_UNSPECIFIED;
}

const char* decision_name(v1::Decision value) {
  for (const Named& d : kDecisions)
    if (value == d.value) return d.name;
  return "";
}

}  // namespace rangex
