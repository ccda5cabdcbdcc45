#include "sensors/genicam_url.h"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <vector>

#include "core/error.h"

namespace rangex {

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out(1);
  for (char c : s)
    if (c == sep)
      out.emplace_back();
    else
      out.back() += c;
  return out;
}

bool parse_hex(const std::string& s, uint64_t& v) {
  const char* end = s.data() + s.size();
  const auto [p, ec] = std::from_chars(s.data(), end, v, 16);
  return !s.empty() && ec == std::errc() && p == end;
}

}  // namespace

GenicamUrl parse_genicam_url(const std::string& text) {
  const std::string shown = "'" + text.substr(0, 120) + (text.size() > 120 ? "...'" : "'");
  const size_t colon = text.find(':');
  if (colon == std::string::npos || colon == 0)
    fail("GenICam URL ", shown, " names no scheme (Local:, File:)");
  GenicamUrl u;
  u.scheme = lower(text.substr(0, colon));
  std::string rest = text.substr(colon + 1);
  rest = rest.substr(0, rest.find('?'));  // "?SchemaVersion=..."
  if (u.scheme == "file") {
    // "File:PATH" or "file:///PATH".
    if (rest.rfind("///", 0) == 0) rest = rest.substr(2);
    u.path = rest;
    return u;
  }
  if (u.scheme != "local") {
    u.path = rest;
    return u;
  }
  rest.erase(0, std::min(rest.find_first_not_of('/'), rest.size()));
  const std::vector<std::string> parts = split(rest, ';');
  if (parts.size() != 3 || parts[0].empty() || !parse_hex(parts[1], u.address) ||
      !parse_hex(parts[2], u.size))
    fail("GenICam URL ", shown, " is not Local:NAME;ADDRESS;SIZE (hexadecimal)");
  u.path = parts[0];
  return u;
}

std::string genicam_url_refusal(const GenicamUrl& u, uint64_t max_bytes) {
  if (u.scheme == "local") {
    if (u.size == 0) return "it names an empty description";
    if (u.size > max_bytes)
      return join("it declares ", u.size, " bytes, more than the ", max_bytes,
                  " a description may have");
    return "";
  }
  if (u.scheme == "file") {
    struct stat st {};
    if (stat(u.path.c_str(), &st) != 0)
      return join("it names a file of this host that cannot be read (", std::strerror(errno), ")");
    if (!S_ISREG(st.st_mode)) return "it names something of this host that is not a file";
    if (uint64_t(st.st_size) > max_bytes)
      return join("it names a file of ", uint64_t(st.st_size), " bytes, more than the ", max_bytes,
                  " a description may have");
    return "";
  }
  return "rangex reads a description from the device's memory (Local:) or a file (File:) only";
}

}  // namespace rangex
