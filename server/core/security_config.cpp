#include "core/security_config.h"

namespace rangex {

namespace {
constexpr const char* kRoleNames[] = {"none", "viewer", "operator", "engineer", "admin"};
}

const char* role_name(Role r) {
  return kRoleNames[int(r)];
}

std::optional<Role> parse_role(const std::string& s) {
  for (int i = 0; i < 5; ++i)
    if (s == kRoleNames[i]) return Role(i);
  return std::nullopt;
}

}  // namespace rangex
