#pragma once
// The subcommands: each takes its arguments (after the command name) and returns the exit code.
#include <string>
#include <vector>

namespace msk::cli {
/// mskseg info IMAGE
int cmdInfo(const std::vector<std::string>& args);
}  // namespace msk::cli
