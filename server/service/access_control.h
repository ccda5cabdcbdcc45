// Who a client is and what its role allows (plant.yaml `security:`). Transport-free: gRPC
// and the HTTP side each hand over what the connection proved (a verified client
// certificate's common name, an Authorization header, the peer's address) and get back the
// identity the audit log records. A client never names itself.
#pragma once
#include <string>

#include "core/error.h"
#include "core/security_config.h"

namespace rangex {

class Unauthenticated : public Error {  // no identity, or a credential that proves none
 public:
  using Error::Error;
};
class PermissionDenied : public Error {  // an identity whose role does not allow the call
 public:
  using Error::Error;
};

struct Identity {
  std::string name;  // "cert:CN", "token:NAME" or "anonymous@PEER": what the audit records
  Role role = Role::none;
};

class AccessControl {
 public:
  explicit AccessControl(SecurityConfig cfg) : cfg_(std::move(cfg)) {}
  const SecurityConfig& config() const { return cfg_; }

  // A bearer token (the Authorization header's "Bearer T", or Basic's password) is looked up
  // first, then the certificate; without either the client is anonymous. Throws
  // Unauthenticated for a credential that matches nothing (never falling back to anonymous).
  Identity identify(const std::string& cert_cn, const std::string& authorization,
                    const std::string& peer) const;

  // Throws Unauthenticated (anonymous without a role) or PermissionDenied naming the role
  // `what` needs and the one the identity has.
  static void require(const Identity& who, Role needed, const std::string& what);

 private:
  SecurityConfig cfg_;
};

// Refuses (throws Error) to serve `what` ("gRPC", "the dashboard") on `address` beyond
// loopback without TLS, or with no authentication (every client would be admin), unless the
// configuration says insecure: true.
void check_listen_security(const std::string& address, const SecurityConfig& s,
                           const std::string& what);
bool is_loopback_host(const std::string& address);  // host[:port]; localhost, 127/8, ::1

}  // namespace rangex
