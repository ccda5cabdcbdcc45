// `rangexctl CMD --help`: the entries of the full usage text that describe CMD, each under
// the section heading it sits in (e.g. a server command's --server and TLS options).
#pragma once
#include <string>

namespace rangex::cli {

// The usage text's entries whose first word is `command` (an entry: a line indented by two
// spaces, then its lines indented further), with their sections' headings; "" when none.
// A heading: an unindented line, through the line that ends with ':' outside parentheses.
std::string usage_of(const std::string& usage, const std::string& command);

}  // namespace rangex::cli
