// Minimal command-line parsing for rangexctl: positionals and --key value / --flag options,
// with errors that name the option.
#pragma once
#include <map>
#include <set>
#include <string>
#include <vector>

namespace rangex::cli {

class Args {
 public:
  // flags: options that take no value; values: options that take one.
  Args(int argc, char** argv, int first, std::set<std::string> flags, std::set<std::string> values);
  const std::vector<std::string>& positional() const { return pos_; }
  std::string positional(size_t i, const char* what) const;
  bool flag(const std::string& name) const { return flags_.count(name) > 0; }
  bool has(const std::string& name) const { return values_.count(name) > 0; }
  std::string get(const std::string& name, const std::string& def) const;
  std::string require(const std::string& name) const;
  long integer(const std::string& name, long def) const;
  // A number within lo..hi (def when the option is absent); anything else fails naming it.
  double number(const std::string& name, double def, double lo, double hi) const;
  // A comma-separated list of whole numbers from 1 to `max` (def when the option is absent).
  std::vector<int> int_list(const std::string& name, std::vector<int> def, int max) const;
  // --lanes 0,2: lane ids separated by commas (none when the option is absent).
  std::vector<int> lane_ids(const std::string& name) const;
  void expect_positionals(size_t n, const char* usage) const;

 private:
  std::vector<std::string> pos_;
  std::set<std::string> flags_;
  std::map<std::string, std::string> values_;
};

}  // namespace rangex::cli
