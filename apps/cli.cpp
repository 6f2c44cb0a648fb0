#include "cli.h"

#include <cmath>
#include <iostream>

namespace msk::cli {

namespace {

/// Refuses text that is not a finite number.
const CLI::Validator kFinite(
    [](std::string& text) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
        return std::string("expects a finite number, got '") + text + "'";
      return std::string();
    },
    "NUMBER");

}  // namespace

CommandLine::CommandLine(const std::string& command, const std::string& description)
    : CLI::App(description, "mskseg " + command) {
  get_formatter()->column_width(34);
}

bool parseArgs(CLI::App& app, const std::vector<std::string>& args) {
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
  try {
    app.parse(reversed);
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return false;
  } catch (const CLI::ExtrasError&) {
    std::string extra;
    for (const std::string& a : app.remaining()) extra += (extra.empty() ? "" : " ") + a;
    throw UsageError("unknown option or unexpected argument: " + extra);
  } catch (const CLI::ParseError& e) {
    throw UsageError(e.what());
  }
  return true;
}

CLI::Option* addNumber(CLI::App& app, const std::string& name, double& value, const std::string& description) {
  return app.add_option(name, value, description)->check(kFinite);
}

CLI::Option* addVec3(CLI::App& app, const std::string& name, Eigen::Vector3d& value, const std::string& description) {
  return app
      .add_option_function<std::vector<double>>(
          name, [&value](const std::vector<double>& v) { value = Eigen::Vector3d(v[0], v[1], v[2]); }, description)
      ->delimiter(',')
      ->expected(3)
      ->check(kFinite)
      ->type_name("X,Y,Z");
}

}  // namespace msk::cli
