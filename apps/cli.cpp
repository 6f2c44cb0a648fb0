#include "cli.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <sstream>

namespace msk::cli {

namespace {

/// `text` broken into lines of at most `width` characters at spaces.
std::string wrapped(const std::string& text, size_t width) {
  std::string out, line, word;
  std::istringstream words(text);
  while (words >> word) {
    if (!line.empty() && line.size() + 1 + word.size() > width) {
      out += line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  return out + line;
}

/// CLI11's help with the descriptions, the app's text and its footer wrapped to 120 columns.
class WrappingFormatter : public CLI::Formatter {
 public:
  std::string make_option_desc(const CLI::Option* opt) const override {
    return wrapped(CLI::Formatter::make_option_desc(opt), 120 - get_column_width());
  }
  std::string make_description(const CLI::App* app) const override {
    const std::string text = app->get_description();
    return text.empty() ? "" : wrapped(text, 120) + "\n\n";
  }
  std::string make_footer(const CLI::App* app) const override {
    const std::string text = app->get_footer();
    return text.empty() ? "" : wrapped(text, 120) + "\n";
  }
};

/// Refuses text that is not a finite number.
const CLI::Validator kFinite(
    [](std::string& text) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
        return std::string("expects a finite number, got '") + text + "'";
      return std::string();
    },
    "");

}  // namespace

CommandLine::CommandLine(const std::string& command, const std::string& description)
    : CLI::App(description, "mskseg " + command) {
  auto formatter = std::make_shared<WrappingFormatter>();
  formatter->column_width(34);
  this->formatter(formatter);
}

namespace {
/// `arg` with the underscores of its option name turned into hyphens when the app has that option and not the
/// underscored one ("--init_transform" -> "--init-transform"), the form of 3D Slicer's module flags.
std::string hyphenated(const CLI::App& app, const std::string& arg) {
  if (arg.rfind("--", 0) != 0) return arg;
  const size_t eq = arg.find('=');
  std::string name = arg.substr(0, eq);
  if (name.find('_') == std::string::npos || app.get_option_no_throw(name) != nullptr) return arg;
  std::replace(name.begin(), name.end(), '_', '-');
  if (app.get_option_no_throw(name) == nullptr) return arg;
  return eq == std::string::npos ? name : name + arg.substr(eq);
}
}  // namespace

bool parseArgs(CLI::App& app, const std::vector<std::string>& args) {
  std::vector<std::string> reversed;  // CLI11 takes them last first
  for (auto a = args.rbegin(); a != args.rend(); ++a) reversed.push_back(hyphenated(app, *a));
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

CLI::Option* addMeshSpace(CLI::App& app, MeshSpace& space, const std::string& description) {
  return app.add_option_function<std::string>(
      "--mesh-space", [&space](const std::string& s) { space = parseMeshSpace(s); }, description);
}

void requireMeshOutput(const std::string& path) {
  if (!isMeshFile(path))
    throw UsageError("unsupported output extension for '" + path + "' (use .vtk .vtp .stl .obj .ply)");
}

}  // namespace msk::cli
