// An image kept by the server that took it, fetched through that server's dashboard for the
// fleet view: the requester's credentials go along (the plant's servers share one plant
// file, so one token reads every dashboard), and a server that cannot be reached is named.
#pragma once
#include <string>

namespace rangex {

struct RelayedImage {
  int status = 0;          // the server's answer, or 502 when it could not be reached
  std::string body, type;  // the image, or {"error": ...} naming the server
};

struct ImageRelayRequest {
  std::string server, url;    // the server's id and its dashboard ("http://host:port")
  std::string path;           // "/api/fillets/UID/images/KIND" (and "?raw=1")
  std::string authorization;  // the requester's Authorization header, passed on
  double timeout_s = 5;
  std::string ca_file;  // verifies an https dashboard ("" : the system's CAs)
};

RelayedImage relay_image(const ImageRelayRequest& r);

}  // namespace rangex
