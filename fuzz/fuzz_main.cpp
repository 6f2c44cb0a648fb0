// libFuzzer entry of one target, chosen when the program is built (MSK_FUZZ_TARGET).
#include <cstdio>
#include <cstdlib>

#include "msk/core/log.h"
#include "targets.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  msk::log::setLevel(msk::LogLevel::Error);  // warnings about accepted-but-odd inputs would flood the output
  if (!msk::fuzz::findTarget(MSK_FUZZ_TARGET)) {
    std::fprintf(stderr, "mskseg fuzz: unknown target %s\n", MSK_FUZZ_TARGET);
    std::abort();
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const msk::fuzz::Target* target = msk::fuzz::findTarget(MSK_FUZZ_TARGET);
  target->run(data, size);
  return 0;
}
