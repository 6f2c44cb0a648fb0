// Replays every fuzz target's seed corpus (fuzz/corpus/<target>/) and every input that ever made a target fail
// (fuzz/regressions/<target>/) through the target itself: each must be read or refused with an msk::Error. A finding
// aborts the test program with the target's message.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <ostream>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "targets.h"

namespace fs = std::filesystem;

namespace {

std::vector<fs::path> filesIn(const fs::path& dir) {
  std::vector<fs::path> files;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::string bytesOf(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

namespace msk::fuzz {
// Test names and failure messages show the target's name.
void PrintTo(const Target& t, std::ostream* os) { *os << t.name; }
}  // namespace msk::fuzz

namespace {

class FuzzReplay : public ::testing::TestWithParam<msk::fuzz::Target> {};

TEST_P(FuzzReplay, SeedsAndRegressionsAreReadOrRefusedWithAnMskError) {
  const auto quiet = msk::log::setSink([](msk::LogLevel, const std::string&) {});
  const fs::path root = fs::path(MSK_SOURCE_DIR) / "fuzz";
  const std::vector<fs::path> seeds = filesIn(root / "corpus" / GetParam().name);
  std::vector<fs::path> inputs = seeds;
  for (const fs::path& p : filesIn(root / "regressions" / GetParam().name)) inputs.push_back(p);
  ASSERT_GE(seeds.size(), 2u) << "each target keeps a seed corpus in fuzz/corpus/" << GetParam().name;
  for (const fs::path& p : inputs) {
    SCOPED_TRACE(p.string());
    const std::string bytes = bytesOf(p);
    GetParam().run(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
  }
  msk::log::setSink(quiet);
}

INSTANTIATE_TEST_SUITE_P(Targets, FuzzReplay, ::testing::ValuesIn(msk::fuzz::targets()),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
