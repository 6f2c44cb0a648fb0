#include "args.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace msk::cli {

Args::Args(const std::vector<std::string>& argv, const std::set<std::string>& valued,
           const std::set<std::string>& flags) {
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.size() > 2 && a.compare(0, 2, "--") == 0) {
      std::string name = a.substr(2), value;
      bool inlineValue = false;
      auto eq = name.find('=');
      if (eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
        inlineValue = true;
      }
      if (flags.count(name)) {
        if (inlineValue) throw UsageError("option --" + name + " takes no value");
        flagsSet_.insert(name);
      } else if (valued.count(name)) {
        if (!inlineValue) {
          if (i + 1 >= argv.size()) throw UsageError("option --" + name + " needs a value");
          value = argv[++i];
        }
        if (values_.count(name)) throw UsageError("option --" + name + " given twice");
        values_[name] = value;
      } else {
        throw UsageError("unknown option --" + name);
      }
    } else {
      positional_.push_back(a);
    }
  }
}

bool Args::has(const std::string& name) const { return values_.count(name) || flagsSet_.count(name); }

std::string Args::str(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) throw UsageError("missing required option --" + name);
  return it->second;
}

std::string Args::str(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

double parseNumber(const std::string& option, const std::string& text) {
  char* end = nullptr;
  double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
    throw UsageError("option --" + option + " expects a number, got '" + text + "'");
  return v;
}

double Args::num(const std::string& name, double fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : parseNumber(name, it->second);
}

long Args::integer(const std::string& name, long fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  char* end = nullptr;
  long v = std::strtol(it->second.c_str(), &end, 10);
  if (it->second.empty() || end != it->second.c_str() + it->second.size())
    throw UsageError("option --" + name + " expects an integer, got '" + it->second + "'");
  return v;
}

Eigen::Vector3d Args::vec3(const std::string& name, const Eigen::Vector3d& fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  std::vector<std::string> parts;
  std::stringstream ss(it->second);
  std::string p;
  while (std::getline(ss, p, ',')) parts.push_back(p);
  if (parts.size() != 3) throw UsageError("option --" + name + " expects three comma-separated numbers, got '" + it->second + "'");
  return {parseNumber(name, parts[0]), parseNumber(name, parts[1]), parseNumber(name, parts[2])};
}

}  // namespace msk::cli
