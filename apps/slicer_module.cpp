#include "slicer_module.h"

#include <iostream>
#include <sstream>
#include <stdexcept>

#include "commands.h"

namespace msk::cli {

namespace {

/// "--init-transform" -> "init_transform": a name and long flag of the form the Execution Model allows.
std::string flagName(const std::string& option) {
  std::string name = option.substr(option.find_first_not_of('-'));
  for (char& c : name)
    if (c == '-') c = '_';
  return name;
}

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void writeParameter(std::ostream& x, const CLI::App& app, const SlicerParameter& p) {
  const CLI::Option* opt = app.get_option_no_throw(p.option);
  if (opt == nullptr) throw std::logic_error("Slicer module: " + p.option + " is not an option of the command");
  x << "    <" << p.tag;
  if (!p.imageType.empty()) x << " type=\"" << p.imageType << "\"";
  if (!p.fileExtensions.empty()) x << " fileExtensions=\"" << p.fileExtensions << "\"";
  if (p.hidden) x << " hidden=\"true\"";
  x << ">\n";
  x << "      <name>" << flagName(p.option) << "</name>\n";
  x << "      <longflag>" << flagName(p.option) << "</longflag>\n";
  x << "      <description>" << markupEscaped(opt->get_description()) << "</description>\n";
  x << "      <label>" << markupEscaped(p.label) << "</label>\n";
  if (!p.defaultValue.empty()) x << "      <default>" << markupEscaped(p.defaultValue) << "</default>\n";
  x << "      <channel>" << p.channel << "</channel>\n";
  if (p.hasRange)
    x << "      <constraints>\n        <minimum>" << number(p.minimum) << "</minimum>\n        <maximum>"
      << number(p.maximum) << "</maximum>\n        <step>" << number(p.step) << "</step>\n      </constraints>\n";
  for (const std::string& e : p.elements) x << "      <element>" << markupEscaped(e) << "</element>\n";
  x << "    </" << p.tag << ">\n";
}

}  // namespace

std::string slicerModuleXml(const CLI::App& app, const SlicerModule& module) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<executable>\n";
  x << "  <category>Segmentation.mskseg</category>\n";
  x << "  <title>" << markupEscaped(module.title) << "</title>\n";
  x << "  <description>" << markupEscaped(module.description) << "</description>\n";
  x << "  <version>" << MSK_VERSION << "</version>\n";
  x << "  <contributor>the mskseg developers</contributor>\n";
  for (const SlicerGroup& g : module.groups) {
    x << "  <parameters" << (g.advanced ? " advanced=\"true\"" : "") << ">\n";
    x << "    <label>" << markupEscaped(g.label) << "</label>\n";
    x << "    <description>" << markupEscaped(g.description) << "</description>\n";
    for (const SlicerParameter& p : g.parameters) writeParameter(x, app, p);
    x << "  </parameters>\n";
  }
  x << "</executable>\n";
  return x.str();
}

SlicerParameter progressTagsParameter() {
  return SlicerParameter("boolean", "--progress-tags", "Progress in Slicer").byDefault("true").hide();
}

bool handleSlicerXml(CLI::App& app, const std::vector<std::string>& args, const SlicerModule& module) {
  app.add_flag("--xml", "print the command's description as a 3D Slicer CLI module (Execution Model XML) and exit");
  for (const std::string& a : args)
    if (a == "--xml") {
      std::cout << slicerModuleXml(app, module);
      return true;
    }
  return false;
}

void addProgressTagsOption(CLI::App& app) {
  app.add_flag_function(
      "--progress-tags", [](std::int64_t) { setProgressTags(true); },
      "progress also on stdout as <filter-progress> tags (3D Slicer's progress bar)");
}

}  // namespace msk::cli
