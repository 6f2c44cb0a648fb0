#pragma once
/// Final separation of touching closed surfaces (the output meshes of a scene): every vertex or face centroid of one
/// surface found inside or within the gap of a declared partner is moved out with the collision position correction of
/// Table 4.23 (spring target, DESIGN-NOTES §3), shared with the partner triangle's corners so linear momentum is
/// conserved. The side is decided by the partner's winding number, which stays right where a surface folds.
#include <memory>
#include <vector>

#include "msk/core/triangle_mesh.h"

namespace msk {

/// Settings of separateSurfaces() (user input).
struct SeparationOptions {
  double reachMm = 3.0;  ///< how far from a partner's surface vertices are examined (> gap), mm
  double maxReachMm =
      10.0;            ///< a pair found deeper inside each other gets a reach covering its deepest vertex, up to this
  int maxSweeps = 32;  ///< sweeps over every pair and direction
  double toleranceMm = 0.05;  ///< a sweep that found nothing inside and corrected nothing by more calls the check, mm
  int threads = 1;  ///< threads (0 = all cores); pairs sharing no surface run together, same result for any count
};

/// One declared pair of surfaces (indices into the surfaces given) and the clearance kept between them.
struct SeparationPair {
  int a = 0, b = 0;    ///< surface indices, a ≠ b
  double gapMm = 0.2;  ///< wanted clearance g ≥ 0, mm
};

/// What separateSurfaces() did.
struct SeparationReport {
  int sweeps = 0;        ///< sweeps run
  long corrections = 0;  ///< vertex corrections applied over all sweeps
  long skipped = 0;      ///< samples the full checks passed over: out of reach, or outside too far to be corrected
  bool clean = false;    ///< the last sweep (a full check) found no sample inside a partner
};

/// What a separateSurfaces() run learnt of each sample (the partner triangle it found, a distance no part of the
/// partner was nearer than, its side) and how far each surface has travelled, for a later run on the same surfaces and
/// pairs: that run's full checks skip the samples that cannot have come near their partner since. A move of the
/// surfaces made between the runs must be declared with moved().
class SeparationMemory {
 public:
  SeparationMemory();
  ~SeparationMemory();
  SeparationMemory(const SeparationMemory&) = delete;
  SeparationMemory& operator=(const SeparationMemory&) = delete;
  /// Surface `surface`'s vertices moved by at most `mm` each since the last run.
  void moved(int surface, double mm);

  struct Samples;  ///< per pair and direction, what the queries learnt (surface_separation.cpp)
  std::unique_ptr<Samples> samples;
  std::vector<double> travelled;  ///< per surface, mm (see SeparationState)
};

/// Moves the surfaces' vertices (in place) until a full check (every sample, side from the winding number) finds no
/// sample (vertex or face centroid) of either surface of a pair inside the other, or maxSweeps is reached. Pairs that
/// share no surface run in parallel (colour by colour, so any thread count gives the same surfaces); a pair found with
/// nothing to do is skipped until another pair moves one of its surfaces. `inverseMass` gives each surface's (uniform)
/// inverse mass: a heavier surface (a bone) moves less. Throws ParameterError for bad options or pair indices, Error on
/// size mismatches.
/// `memory` (optional): what an earlier run on the same surfaces and pairs learnt, updated for the next.
SeparationReport separateSurfaces(std::vector<TriangleMesh*>& surfaces, const std::vector<double>& inverseMass,
                                  const std::vector<SeparationPair>& pairs, const SeparationOptions& opts = {},
                                  SeparationMemory* memory = nullptr);

/// Deepest vertex of `a` inside closed surface `b`, mm (0 if none): winding-number side, depth = distance to b's
/// surface. A vertex inside but farther than `reachMm` from b's surface counts as `reachMm` (a lower bound).
double penetrationDepth(const TriangleMesh& a, const TriangleMesh& b, double reachMm = 10.0);

}  // namespace msk
