// mskseg: one program, many subcommands. Turns every error into one line on stderr and an exit code:
// 0 ok, 1 failure (bad input, I/O), 2 usage error (bad command line or parameter).
#include <malloc.h>  // mallopt (glibc)

#include <cstdio>
#include <exception>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "cli.h"
#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"

namespace {

struct Command {
  std::function<int(const std::vector<std::string>&)> run;
  const char* summary;
};

const std::map<std::string, Command>& commands() {
  static const std::map<std::string, Command> table = {
      {"atlas", {msk::cli::cmdAtlas, "atlas folder (reference image, templates, scene) from a subject's labels"}},
      {"info", {msk::cli::cmdInfo, "describe a NIfTI volume (geometry, affine source, datatype, range) or a mesh"}},
      {"segment", {msk::cli::cmdSegment, "segment the objects of a scene (templates -> surfaces, labels, report, QC)"}},
      {"phantom", {msk::cli::cmdPhantom, "generate a synthetic thigh MRI with exact ground truth"}},
      {"eval", {msk::cli::cmdEval, "Dice, Jaccard, ASSD, HD95, Hausdorff between label maps or meshes"}},
      {"rasterize", {msk::cli::cmdRasterize, "closed mesh -> label map on an image's grid"}},
      {"convert", {msk::cli::cmdConvert, "convert meshes between .vtk .vtp .stl .obj .ply and LPS/RAS"}},
      {"scene",
       {msk::cli::cmdScene, "scene.json and templates from a label map's labels (e.g. the other side, mirrored)"}},
      {"template", {msk::cli::cmdTemplate, "smooth template surface from a label map"}},
      {"batch",
       {msk::cli::cmdBatch, "segment every case of a cohort folder with one scene (resumable, summary table)"}},
      {"collect",
       {msk::cli::cmdCollect,
        "summary tables of a cohort segmented case by case (the Snakemake workflow's last step)"}},
      {"bench", {msk::cli::cmdBench, "benchmarks that print figures (bench scene: 24-structure phantom timing)"}},
  };
  return table;
}

void printHelp() {
  std::cout << "mskseg " << MSK_VERSION
            << ": segment bones and muscles in MRI/CT volumes with deformable simplex meshes\n\n"
               "usage: mskseg <command> [options]     (mskseg <command> --help for its options)\n\ncommands:\n";
  for (const auto& kv : commands()) std::printf("  %-10s %s\n", kv.first.c_str(), kv.second.summary);
  std::cout << "\nglobal options: --help, --version, --quiet (warnings and errors only), --verbose\n"
               "exit codes: 0 ok, 1 failure (bad input or I/O), 2 usage error\n"
               "world coordinates: NIfTI RAS mm internally; mesh files LPS with a SPACE tag unless --mesh-space ras\n";
}

/// The command a copy of the program runs as, from its name: "mskseg-segment" runs as `mskseg segment` (the 3D Slicer
/// modules); "" for mskseg itself.
std::string commandOfProgramName(const char* argv0) {
  std::string name = argv0 == nullptr ? "" : argv0;
  name = name.substr(name.find_last_of('/') + 1);
  const std::string prefix = "mskseg-";
  if (name.rfind(prefix, 0) != 0) return "";
  const std::string command = name.substr(prefix.size());
  return commands().count(command) ? command : "";
}

}  // namespace

int main(int argc, char** argv) {
  // Volumes and their working copies (megabytes each) are allocated and freed many times a run. glibc's default
  // serves each from a fresh mmap, whose pages the kernel then faults in and zeroes on every first touch; from the
  // heap, freed blocks are reused instead (a femur's segmentation about 15 % faster). The heap is not trimmed back.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  std::vector<std::string> args(argv + 1, argv + argc);
  if (const std::string command = commandOfProgramName(argv[0]); !command.empty()) args.insert(args.begin(), command);
  msk::LogLevel level = msk::LogLevel::Info;
  std::vector<std::string> rest;
  for (const auto& a : args) {
    if (a == "--quiet")
      level = msk::LogLevel::Warn;
    else if (a == "--verbose")
      level = msk::LogLevel::Debug;
    else
      rest.push_back(a);
  }
  msk::log::setLevel(level);
  msk::log::setSink([](msk::LogLevel l, const std::string& m) {
    static const char* names[] = {"debug", "info", "warning", "error"};
    std::cerr << "mskseg: " << names[static_cast<int>(l)] << ": " << msk::printableText(m) << std::endl;
  });
  if (rest.empty() || rest[0] == "--help" || rest[0] == "-h" || rest[0] == "help") {
    printHelp();
    return rest.empty() ? 2 : 0;
  }
  if (rest[0] == "--version") {
    std::cout << "mskseg " << MSK_VERSION << "\n";
    return 0;
  }
  auto it = commands().find(rest[0]);
  if (it == commands().end()) {
    std::cerr << "mskseg: error: unknown command '" << msk::printableText(rest[0]) << "' (see mskseg --help)\n";
    return 2;
  }
  try {
    return it->second.run(std::vector<std::string>(rest.begin() + 1, rest.end()));
  } catch (const msk::cli::UsageError& e) {
    std::cerr << "mskseg " << rest[0] << ": usage error: " << msk::printableText(e.what()) << " (see mskseg " << rest[0]
              << " --help)\n";
    return 2;
  } catch (const msk::ParameterError& e) {
    std::cerr << "mskseg " << rest[0] << ": usage error: " << msk::printableText(e.what()) << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "mskseg " << rest[0] << ": error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "mskseg " << rest[0] << ": error: " << msk::printableText(e.what()) << "\n";
    return 1;
  }
}
