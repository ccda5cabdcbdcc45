#include "core/host_port.h"

namespace rangex {

int port_of(const std::string& address) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos) return -1;
  const std::string p = address.substr(colon + 1);
  if (p.empty() || p.size() > 5 || p.find_first_not_of("0123456789") != std::string::npos)
    return -1;
  const int port = std::stoi(p);
  return port <= 65535 ? port : -1;
}

}  // namespace rangex
