#pragma once
/// Graph colouring of constraints for parallel Gauss–Seidel and deterministic accumulation: constraints of one colour
/// share no particle, so they can be projected at the same time in any order with the same result.
#include <functional>
#include <vector>

namespace msk {

/// Constraints grouped by colour: colour k holds order[start[k] .. start[k+1]), ascending constraint indices.
struct Colouring {
  std::vector<int> order;  ///< constraint indices, colour by colour
  std::vector<int> start;  ///< #colours + 1 offsets into `order`

  /// Number of colours.
  int colours() const { return start.empty() ? 0 : static_cast<int>(start.size()) - 1; }
};

/// Greedy first-fit colouring in constraint order: each of the `count` constraints gets the smallest colour not yet
/// used by a constraint sharing one of its particles. `particlesOf(c, out)` writes constraint c's particle indices
/// (≥ 0) to `out` (room for `maxParticles`) and returns their number. Deterministic; at most Δ + 1 colours, Δ the
/// largest number of other constraints a constraint shares particles with.
Colouring colourConstraints(int count, int maxParticles, const std::function<int(int, int*)>& particlesOf);

}  // namespace msk
