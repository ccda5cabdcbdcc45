#include "core/security_config.h"

namespace rangex {

namespace {
constexpr const char* kNames[] = {"none", "viewer", "operator", "engineer", "admin"};
}

const char* role_name(Role r) {
  return kNames[int(r)];
}

std::optional<Role> parse_role(const std::string& s) {
  for (int i = 0; i < 5; ++i)
    if (s == kNames[i]) return Role(i);
  return std::nullopt;
}

}  // namespace rangex
