#include "args.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "core/error.h"

namespace rangex::cli {

Args::Args(int argc, char** argv, int first, std::set<std::string> flags,
           std::set<std::string> values) {
  for (int i = first; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--", 0) == 0) {
      const std::string name = a.substr(2);
      if (flags.count(name)) {
        flags_.insert(name);
      } else if (values.count(name)) {
        if (i + 1 >= argc) fail("option --", name, " needs a value");
        values_[name] = argv[++i];
      } else {
        std::string known;
        for (const auto& f : flags) known += " --" + f;
        for (const auto& v : values) known += " --" + v;
        fail("unknown option ", a, " (known:", known.empty() ? " none" : known, ")");
      }
    } else {
      pos_.push_back(a);
    }
  }
}

std::string Args::positional(size_t i, const char* what) const {
  if (i >= pos_.size()) fail("missing ", what);
  return pos_[i];
}

std::string Args::get(const std::string& name, const std::string& def) const {
  auto it = values_.find(name);
  return it == values_.end() ? def : it->second;
}

std::string Args::require(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) fail("missing option --", name);
  return it->second;
}

long Args::integer(const std::string& name, long def) const {
  auto it = values_.find(name);
  if (it == values_.end()) return def;
  try {
    size_t used = 0;
    const long v = std::stol(it->second, &used);
    if (used != it->second.size()) throw std::invalid_argument("trailing");
    return v;
  } catch (const std::exception&) {
    fail("option --", name, " expects an integer (got '", it->second, "')");
  }
}

double Args::number(const std::string& name, double def, double lo, double hi) const {
  if (!has(name)) return def;
  const std::string v = get(name, "");
  double x = NAN;
  try {
    size_t used = 0;
    x = std::stod(v, &used);
    if (used != v.size()) x = NAN;
  } catch (const std::exception&) {
  }
  if (!(x >= lo && x <= hi))
    fail("--", name, " must be a number within ", lo, "..", hi, " (got '", v, "')");
  return x;
}

std::vector<int> Args::int_list(const std::string& name, std::vector<int> def, int max) const {
  if (!has(name)) return def;
  const std::string v = get(name, "");
  std::vector<int> out;
  for (size_t i = 0; i <= v.size();) {
    const size_t j = std::min(v.find(',', i), v.size());
    const std::string item = v.substr(i, j - i);
    char* end = nullptr;
    const long n = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end || n < 1 || n > max)
      fail("--", name, " takes numbers from 1 to ", max, " separated by commas (got '", v, "')");
    out.push_back(int(n));
    i = j + 1;
  }
  return out;
}

std::vector<int> Args::lane_ids(const std::string& name) const {
  const std::string v = get(name, "");
  std::vector<int> out;
  std::stringstream ss(v);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty() || item.find_first_not_of("0123456789") != std::string::npos ||
        item.size() > 6)
      fail("--", name, " must be lane ids separated by commas (got '", v, "')");
    out.push_back(std::stoi(item));
  }
  return out;
}

void Args::expect_positionals(size_t n, const char* usage) const {
  if (pos_.size() != n) fail("expected ", n, " argument", n == 1 ? "" : "s", ": ", usage);
}

}  // namespace rangex::cli
