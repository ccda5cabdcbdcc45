// rangexctl token: a new bearer token for one identity and role. The token is printed once;
// plant.yaml keeps only its SHA-256, so a leaked configuration grants nothing.
#include <cstdio>
#include <fstream>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "core/security_config.h"
#include "store/sha256_hex.h"

namespace rangex::cli {

int cmd_token(int argc, char** argv) {
  const Args a(argc, argv, 2, {}, {"name", "role", "out"});
  a.expect_positionals(0, "token --name NAME --role viewer|operator|engineer|admin [--out FILE]");
  const std::string name = a.require("name"), role = a.require("role");
  const auto r = parse_role(role);
  if (!r || *r == Role::none)
    fail("--role must be one of viewer, operator, engineer, admin (got '", role, "')");
  unsigned char raw[32];
  std::ifstream rnd("/dev/urandom", std::ios::binary);
  if (!rnd.read(reinterpret_cast<char*>(raw), sizeof raw)) fail("cannot read /dev/urandom");
  static const char* hex = "0123456789abcdef";
  std::string token = "rgx_";
  for (unsigned char b : raw) token += {hex[b >> 4], hex[b & 15]};
  if (a.has("out")) {
    std::ofstream out(a.get("out", ""), std::ios::trunc);
    if (!(out << token << "\n")) fail("--out: cannot write ", a.get("out", ""));
    std::printf("token for %s (%s) written to %s\n", name.c_str(), role.c_str(),
                a.get("out", "").c_str());
  } else {
    std::printf("token (shown once; give it to the client as RANGEX_TOKEN): %s\n", token.c_str());
  }
  std::printf("add to plant.yaml security.tokens:\n    - {name: %s, role: %s, sha256: %s}\n",
              name.c_str(), role.c_str(), sha256_hex(token).c_str());
  return 0;
}

}  // namespace rangex::cli
