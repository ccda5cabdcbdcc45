// Who may do what (plant.yaml `security:`): TLS for gRPC and the dashboard, the identities a
// client proves (a client certificate's common name, or a bearer token whose SHA-256 is
// listed), and the role each identity holds. Roles are ordered; each includes the ones below.
#pragma once
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rangex {

enum class Role {
  none = 0,   // may do nothing (an unauthenticated client where authentication is configured)
  viewer,     // results, images, statistics, lanes, calibrations (read)
  operator_,  // + feeding lines, lane thresholds, lane resets
  engineer,   // + calibration upload and activation
  admin,      // + overrides of the server's own checks (forced calibration activation)
};

const char* role_name(Role r);
std::optional<Role> parse_role(const std::string& s);  // nullopt when not a role's name

struct TokenEntry {
  std::string name;  // the identity the audit log records
  Role role = Role::none;
  std::string sha256;  // of the token, lower-case hex: plant.yaml never holds the token itself
};

struct SecurityConfig {
  // TLS (both empty: plaintext). Paths to PEM files, relative to rangexd's working directory.
  std::string tls_cert, tls_key;
  // Clients presenting a certificate must be signed by this CA; its common name is the identity.
  std::string client_ca;
  std::map<std::string, Role> identities;  // certificate common name -> role
  std::vector<TokenEntry> tokens;
  // The role of a client that proves no identity. Unset: admin when no authentication is
  // configured (the loopback zero-config default), none otherwise.
  std::optional<Role> anonymous;
  // Allows listening beyond loopback without TLS, or with no authentication.
  bool insecure = false;

  bool tls() const { return !tls_cert.empty(); }
  bool authenticates() const { return !client_ca.empty() || !tokens.empty(); }
  Role anonymous_role() const {
    return anonymous ? *anonymous : authenticates() ? Role::none : Role::admin;
  }
};

}  // namespace rangex
