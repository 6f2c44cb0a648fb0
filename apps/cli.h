#pragma once
// Command-line parsing for the mskseg subcommands (CLI11): each subcommand binds its options into the structs it
// fills, parseArgs() turns CLI11's errors into UsageError (exit code 2), and --help prints the generated help.
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <string>
#include <vector>

#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"

namespace msk::cli {

/// A malformed command line: printed with a hint to --help, exit code 2.
class UsageError : public Error {
 public:
  using Error::Error;
};

/// The parser of one subcommand ("mskseg <command>" in its help), described by `description`.
class CommandLine : public CLI::App {
 public:
  CommandLine(const std::string& command, const std::string& description);
};

/// Parses `args` (what follows the command name) into what `app` binds. Returns false if --help was asked (the help
/// is then printed on stdout); throws UsageError naming the option for anything malformed.
/// Options are also accepted with underscores for hyphens (--init_transform), the form 3D Slicer passes.
bool parseArgs(CLI::App& app, const std::vector<std::string>& args);

/// An option taking a finite number (NaN and infinities are refused) bound to `value`.
CLI::Option* addNumber(CLI::App& app, const std::string& name, double& value, const std::string& description);

/// An option taking three finite numbers "x,y,z" bound to `value`.
CLI::Option* addVec3(CLI::App& app, const std::string& name, Eigen::Vector3d& value, const std::string& description);

/// The option --mesh-space ("lps" or "ras", the space mesh files are written in) bound to `space`.
CLI::Option* addMeshSpace(CLI::App& app, MeshSpace& space, const std::string& description);

/// Throws UsageError naming `path` unless its extension is one of the mesh formats written (isMeshFile()).
void requireMeshOutput(const std::string& path);

}  // namespace msk::cli
