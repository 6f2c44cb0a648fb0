#include "msk/core/graph_colouring.h"

#include <algorithm>
#include <cstdint>

#include "msk/core/error.h"

namespace msk {

Colouring colourConstraints(int count, int maxParticles, const std::function<int(int, int*)>& particlesOf) {
  Colouring out;
  out.start.push_back(0);
  if (count <= 0) return out;
  // Particles per constraint, gathered once (CSR).
  std::vector<int> first(static_cast<size_t>(count) + 1, 0), parts;
  std::vector<int> buf(static_cast<size_t>(std::max(1, maxParticles)));
  parts.reserve(static_cast<size_t>(count) * static_cast<size_t>(std::max(1, maxParticles)));
  int maxIndex = -1;
  for (int c = 0; c < count; ++c) {
    const int k = particlesOf(c, buf.data());
    MSK_ASSERT(k >= 0 && k <= maxParticles, "colourConstraints: bad particle count");
    for (int i = 0; i < k; ++i) {
      MSK_ASSERT(buf[static_cast<size_t>(i)] >= 0, "colourConstraints: negative particle index");
      parts.push_back(buf[static_cast<size_t>(i)]);
      maxIndex = std::max(maxIndex, buf[static_cast<size_t>(i)]);
    }
    first[static_cast<size_t>(c) + 1] = static_cast<int>(parts.size());
  }
  // First fit with a bit set of used colours per particle; widen the sets and start again if they overflow.
  std::vector<int> colour(static_cast<size_t>(count));
  int words = 1, colours = 0;
  for (;;) {
    std::vector<std::uint64_t> used(static_cast<size_t>(maxIndex + 1) * static_cast<size_t>(words), 0);
    colours = 0;
    bool overflow = false;
    for (int c = 0; c < count && !overflow; ++c) {
      int chosen = -1;
      for (int wd = 0; wd < words && chosen < 0; ++wd) {
        std::uint64_t taken = 0;
        for (int i = first[static_cast<size_t>(c)]; i < first[static_cast<size_t>(c) + 1]; ++i)
          taken |= used[static_cast<size_t>(parts[static_cast<size_t>(i)]) * static_cast<size_t>(words) +
                        static_cast<size_t>(wd)];
        if (taken != ~std::uint64_t(0))
          for (int b = 0; b < 64; ++b)
            if (!(taken & (std::uint64_t(1) << b))) {
              chosen = wd * 64 + b;
              break;
            }
      }
      if (chosen < 0) {
        overflow = true;
        break;
      }
      colour[static_cast<size_t>(c)] = chosen;
      colours = std::max(colours, chosen + 1);
      for (int i = first[static_cast<size_t>(c)]; i < first[static_cast<size_t>(c) + 1]; ++i)
        used[static_cast<size_t>(parts[static_cast<size_t>(i)]) * static_cast<size_t>(words) +
             static_cast<size_t>(chosen / 64)] |= std::uint64_t(1) << (chosen % 64);
    }
    if (!overflow) break;
    words *= 2;
  }
  // Counting sort by colour keeps ascending constraint order within a colour.
  out.start.assign(static_cast<size_t>(colours) + 1, 0);
  for (int c = 0; c < count; ++c) ++out.start[static_cast<size_t>(colour[static_cast<size_t>(c)]) + 1];
  for (int k = 0; k < colours; ++k) out.start[static_cast<size_t>(k) + 1] += out.start[static_cast<size_t>(k)];
  out.order.resize(static_cast<size_t>(count));
  std::vector<int> fill(out.start.begin(), out.start.end() - 1);
  for (int c = 0; c < count; ++c)
    out.order[static_cast<size_t>(fill[static_cast<size_t>(colour[static_cast<size_t>(c)])]++)] = c;
  return out;
}

}  // namespace msk
