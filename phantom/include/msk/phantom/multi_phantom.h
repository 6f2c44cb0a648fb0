#pragma once
/// Synthetic T1-weighted MRI of both thighs and both lower legs with exact ground truth: 24 structures (4 bones,
/// 20 muscles) for scaling benchmarks of multi-object scenes.
#include "msk/core/log.h"
#include "msk/phantom/phantom.h"

namespace msk {

/// Number of structures of the multi-structure phantom: a bone and five muscle compartments in each of four limb
/// segments.
constexpr int kMultiPhantomStructures = 24;

/// Generates the multi-structure phantom in memory, in RAS mm (+x the subject's right, +y anterior, +z superior), the
/// knees at z = 0. Each limb segment (right thigh, left thigh, right lower leg, left lower leg, in this order) is the
/// thigh phantom's limb model (phantom.h) with five compartments: a bone (label 6s+1, "bone": femur or tibia) wrapped
/// by five muscles (labels 6s+2..6s+6) that touch the bone (across a 1 mm periosteal fat gap) and their two
/// neighbours, separated by fat septa each missing over one stretch; names are prefixed "r_" / "l_". Touching pairs
/// are listed in PhantomObject::touching (40 pairs). Templates are the mean anatomy (seed-independent); truth,
/// image, noise and bias vary with opts.seed, deterministically. Uses every PhantomOptions field (the un-posed field
/// of view, 290 × 150 × 340 mm, is fixed; opts.pose moves the anatomy and the field of view as in makePhantom());
/// throws ParameterError for invalid options. Write it with writePhantom().
Phantom makeMultiPhantom(const PhantomOptions& opts, const ProgressFn& progress = {});

}  // namespace msk
