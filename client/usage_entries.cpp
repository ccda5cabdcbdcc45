#include "usage_entries.h"

#include <sstream>

namespace rangex::cli {

std::string usage_of(const std::string& usage, const std::string& command) {
  std::istringstream in(usage);
  std::string line, heading, out, printed_heading;
  bool in_heading = false, in_match = false;
  int open = 0;  // a heading's unclosed parentheses
  auto ends_heading = [&](const std::string& l) {
    for (char c : l) open += (c == '(') - (c == ')');
    return open <= 0 && !l.empty() && l.back() == ':';
  };
  while (std::getline(in, line)) {
    if (in_heading && line.empty()) {  // a line that was no heading (the usage's first)
      in_heading = false, heading.clear();
      continue;
    }
    if (in_heading) {  // a heading's further lines, however indented
      heading += line + "\n";
      in_heading = !ends_heading(line);
      continue;
    }
    if (line.empty()) {
      in_match = false;
      continue;
    }
    if (line[0] != ' ') {  // a new section
      heading = line + "\n";
      open = 0;
      in_heading = !ends_heading(line);
      in_match = false;
      continue;
    }
    const bool head = line.size() > 2 && line[2] != ' ';
    if (head) {
      const std::string rest = line.substr(2);
      in_match = rest.compare(0, command.size(), command) == 0 &&
                 (rest.size() == command.size() || rest[command.size()] == ' ');
      if (in_match && printed_heading != heading) {
        if (heading != "commands:\n") out += (out.empty() ? "" : "\n") + heading;
        printed_heading = heading;
      }
    }
    if (in_match) out += line + "\n";
  }
  return out;
}

}  // namespace rangex::cli
