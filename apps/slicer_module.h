#pragma once
// The commands as 3D Slicer CLI modules: `mskseg <command> --xml` prints the command's description in Slicer's
// Execution Model XML, whose parameters are the command's own options, and a copy of the program named
// mskseg-<command> runs as `mskseg <command>` (Slicer runs a module's executable with the arguments it builds from
// that description: `--flag value` pairs, booleans as a bare flag when true).
#include <string>
#include <utility>
#include <vector>

#include "cli.h"

namespace msk::cli {

/// One parameter of a module, bound to an option of the command (its description is the option's help text). Built
/// as SlicerParameter("image", "--image", "Input volume").type("scalar").extensions(".nii.gz").
struct SlicerParameter {
  SlicerParameter(std::string tagName, std::string optionName, std::string panelLabel)
      : tag(std::move(tagName)), option(std::move(optionName)), label(std::move(panelLabel)) {}
  /// An output of the module (channel "output").
  SlicerParameter& output() {
    channel = "output";
    return *this;
  }
  SlicerParameter& type(std::string t) {
    imageType = std::move(t);
    return *this;
  }
  SlicerParameter& extensions(std::string e) {
    fileExtensions = std::move(e);
    return *this;
  }
  SlicerParameter& byDefault(std::string d) {
    defaultValue = std::move(d);
    return *this;
  }
  SlicerParameter& choices(std::vector<std::string> values) {
    elements = std::move(values);
    return *this;
  }
  SlicerParameter& range(double lo, double hi, double by) {
    hasRange = true, minimum = lo, maximum = hi, step = by;
    return *this;
  }
  SlicerParameter& hide() {
    hidden = true;
    return *this;
  }

  std::string tag;     ///< image, geometry, file, directory, boolean, integer, double, string, string-enumeration
  std::string option;  ///< the command's option, e.g. "--init-transform"
  std::string label;   ///< what Slicer's panel shows
  std::string channel = "input";
  std::string imageType;       ///< image: scalar or label; geometry: model
  std::string fileExtensions;  ///< image, geometry, file: the first is the format Slicer exchanges the data in
  std::string defaultValue;
  std::vector<std::string> elements;  ///< string-enumeration: the values
  bool hasRange = false;
  double minimum = 0, maximum = 0, step = 1;  ///< integer and double with hasRange
  bool hidden = false;
};

/// A group of parameters (a collapsible section of the module's panel).
struct SlicerGroup {
  std::string label, description;
  bool advanced = false;
  std::vector<SlicerParameter> parameters;
};

/// A command as a module.
struct SlicerModule {
  std::string title, description;
  std::vector<SlicerGroup> groups;
};

/// The module's Execution Model XML. Each parameter's name and long flag come from its option ("--init-transform":
/// name init_transform, long flag init_transform, which the command accepts; see parseArgs()), its description from
/// the option's help. Throws std::logic_error if a parameter names an option `app` does not have.
std::string slicerModuleXml(const CLI::App& app, const SlicerModule& module);

/// The hidden parameter of --progress-tags, on: the modules of commands that report progress pass it.
SlicerParameter progressTagsParameter();

/// Adds --xml to `app` (shown in its help). Call after every other option is added and before parseArgs(): if `args`
/// holds --xml, prints the module's XML on stdout and returns true (the command then ends).
bool handleSlicerXml(CLI::App& app, const std::vector<std::string>& args, const SlicerModule& module);

/// The option --progress-tags: progress also on stdout as <filter-progress> tags, which 3D Slicer shows in the
/// module's progress bar (the modules pass it, a hidden boolean that is on).
void addProgressTagsOption(CLI::App& app);

}  // namespace msk::cli
