#pragma once
/// The fuzz targets: each feeds one input to one of mskseg's readers (NIfTI, each mesh format, tet meshes, scenes,
/// atlases, linear transforms). The libFuzzer programs (fuzz_<name>) and the replay test share them.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace msk::fuzz {

/// One target. run() returns when the reader accepted the input or refused it with an msk::Error (a message naming
/// the file); anything else (another exception, a crash) is a finding: it prints what it was and aborts.
struct Target {
  const char* name;
  void (*run)(const uint8_t* data, size_t size);
};

/// Every target, in a fixed order.
const std::vector<Target>& targets();

/// The target called `name`, or nullptr.
const Target* findTarget(const std::string& name);

}  // namespace msk::fuzz
