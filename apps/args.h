#pragma once
// Command-line parsing for the mskseg subcommands: --key value / --flag options, typed getters,
// and UsageError (exit code 2) for anything malformed.
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "msk/core/error.h"

namespace msk::cli {

/// A malformed command line: printed with a hint to --help, exit code 2.
class UsageError : public Error {
 public:
  using Error::Error;
};

/// Options of one subcommand, parsed against the set of names it accepts.
class Args {
 public:
  /// `valued`: options taking a value; `flags`: options without. Throws UsageError on anything else.
  Args(const std::vector<std::string>& argv, const std::set<std::string>& valued, const std::set<std::string>& flags);
  /// True if the option or flag was given.
  bool has(const std::string& name) const;
  /// The option's value; throws UsageError if it is required and missing.
  std::string str(const std::string& name) const;
  /// The option's value, or `fallback`.
  std::string str(const std::string& name, const std::string& fallback) const;
  /// A number; throws UsageError if not a finite number.
  double num(const std::string& name, double fallback) const;
  /// An integer; throws UsageError if not an integer.
  long integer(const std::string& name, long fallback) const;
  /// "a,b,c" as a vector of three finite numbers.
  Eigen::Vector3d vec3(const std::string& name, const Eigen::Vector3d& fallback) const;
  /// Arguments that are not options.
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::set<std::string> flagsSet_;
  std::vector<std::string> positional_;
};

/// Parses a finite number, naming the option in the UsageError.
double parseNumber(const std::string& option, const std::string& text);

}  // namespace msk::cli
