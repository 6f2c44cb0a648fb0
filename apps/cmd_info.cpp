#include <iostream>

#include "args.h"
#include "commands.h"

namespace msk::cli {
int cmdInfo(const std::vector<std::string>& argv) {
  Args args(argv, {}, {"help", "json"});
  if (args.has("help") || args.positional().size() != 1) {
    std::cout << "usage: mskseg info IMAGE.nii[.gz] [--json]\n";
    return args.has("help") ? 0 : 2;
  }
  std::cout << "not yet\n";
  return 1;
}
}  // namespace msk::cli
