// A CSV export fetched over HTTP, as its lines (CRLF's '\r' kept): the answer must be a 200
// sent in chunks, a page at a time. Empty, with the failure reported, when it is not.
#pragma once
#include <gtest/gtest.h>
#include <httplib.h>

#include <string>
#include <vector>

namespace rangex::test {

inline std::vector<std::string> csv_export_lines(httplib::Client& c, const std::string& path) {
  c.set_read_timeout(60, 0);  // the bound: an export that stalls fails the test
  const auto r = c.Get(path);
  if (!r) {
    ADD_FAILURE() << path << ": " << httplib::to_string(r.error());
    return {};
  }
  EXPECT_EQ(r->status, 200) << r->body.substr(0, 200);
  EXPECT_EQ(r->get_header_value("Transfer-Encoding"), "chunked");
  std::vector<std::string> lines;
  for (size_t at = 0, end; at < r->body.size(); at = end + 1) {
    end = r->body.find('\n', at);
    if (end == std::string::npos) end = r->body.size();
    lines.push_back(r->body.substr(at, end - at));
  }
  return lines;
}

}  // namespace rangex::test
