// The surfaces written out: separated where declared partners still overlap, unfolded where the separation folded
// them, and rasterised into the label map.
#include <algorithm>

#include "msk/core/surface_separation.h"
#include "msk/imaging/rasterize.h"
#include "msk/segmentation/overlap_repair.h"
#include "msk/segmentation/surface_quality.h"
#include "parallel_each.h"
#include "segment_stages.h"

namespace msk::detail {

std::vector<std::vector<size_t>> separateOutputs(SegmentationResult& res, const std::vector<ObjectState>& objs,
                                                 const Scene& scene, const std::vector<PairContact>& contacts,
                                                 const SegmentOptions& opts, const Grid& grid, bool& crossingsCounted) {
  // The output surfaces (the dual triangle meshes, not the simplex surfaces the contacts acted on) are separated last,
  // so that what is written out and rasterised has no vertex inside a partner; then penetration is measured on them.
  const auto ts = Clock::now();
  std::vector<TriangleMesh*> surfaces;
  std::vector<double> inverseMass;
  for (size_t i = 0; i < res.objects.size(); ++i) {
    surfaces.push_back(&res.objects[i].mesh);
    inverseMass.push_back(scene.objects[i].kind == ObjectKind::Bone ? 1.0 / opts.collision.boneMassRatio : 1.0);
  }
  std::vector<SeparationPair> pairs;
  SeparationOptions so;
  so.maxSweeps = opts.collision.separationSweeps;
  so.threads = opts.evolution.threads;
  so.reachMm = std::max(3.0, 2.0 * defaultProximityMm(opts, grid));
  for (size_t k = 0; k < scene.collisions.size(); ++k) {
    pairs.push_back({scene.collisions[k].a, scene.collisions[k].b, contacts[k].gapMm});
    so.reachMm = std::max(so.reachMm, contacts[k].gapMm + contacts[k].proximityMm);
  }
  SeparationMemory memory;  // what each run learnt of the samples, for the runs after an unfolding
  const SeparationReport sep = separateSurfaces(surfaces, inverseMass, pairs, so, &memory);
  res.separationSweeps = sep.sweeps;
  res.separationCorrections = sep.corrections;
  // The separation moves vertices one by one and can fold a surface squeezed between partners: unfolded, then
  // separated again (twice at most).
  // An unfolding that moved nothing has counted each surface's crossing faces as written, unless a later step moves it.
  crossingsCounted = false;
  for (int again = 0; again < 2 && opts.surface.unfoldSurfaces; ++again) {
    std::vector<int> movedBy(res.objects.size(), 0);
    std::vector<double> moveMm(res.objects.size(), 0.0);
    parallelEach(res.objects.size(), opts.evolution.threads, [&](size_t i) {
      ObjectResult& o = res.objects[i];
      const UnfoldReport u = unfoldSurface(o.mesh);
      o.foldsFound += u.before;
      o.unfoldedVertices += u.verticesMoved;
      o.selfIntersections = u.after;
      movedBy[i] = u.verticesMoved;
      moveMm[i] = u.maxMoveMm;
    });
    for (size_t i = 0; i < res.objects.size(); ++i) memory.moved(static_cast<int>(i), moveMm[i]);
    if (std::all_of(movedBy.begin(), movedBy.end(), [](int m) { return m == 0; })) {
      crossingsCounted = true;
      break;
    }
    const SeparationReport more = separateSurfaces(surfaces, inverseMass, pairs, so, &memory);
    res.separationSweeps += more.sweeps;
    res.separationCorrections += more.corrections;
  }
  const auto tr = Clock::now();
  std::vector<std::vector<size_t>> inside;
  inside.resize(res.objects.size());
  parallelEach(res.objects.size(), opts.evolution.threads,
               [&](size_t i) { inside[i] = insideVoxels(res.objects[i].mesh, grid); });
  res.secondsPerStage["rasterise"] = since(tr);
  // Voxel centres still inside both surfaces of a pair (edges crossing between the separation's samples) go to one.
  double margin = 0;
  std::vector<std::pair<int, int>> repairPairs;
  for (const SeparationPair& p : pairs) {
    margin = std::max(margin, 0.5 * p.gapMm);
    repairPairs.emplace_back(p.a, p.b);
  }
  res.overlapVoxelsRepaired = repairOverlapVoxels(surfaces, repairPairs, grid, margin, inside).handedOver;
  if (res.overlapVoxelsRepaired > 0) crossingsCounted = false;  // the repair moved corners of triangles
  for (size_t i = 0; i < res.objects.size(); ++i) {
    ObjectResult& o = res.objects[i];
    o.mesh.pointData["displacement_mm"] = (o.mesh.vertices - objs[i].lv[0].triangles.vertices).rowwise().norm();
    o.volumeMm3 = enclosedVolume(o.mesh);
    if (objs[i].volume) settleVolumeMesh(o, objs[i].volRestVolumes, objs[i].volSurfaceNode);  // the separated surface
  }
  // Each pair's deepest penetration, the pairs on the threads (each writes its own entry).
  res.pairPenetrationMm.assign(pairs.size(), 0.0);
  parallelEach(pairs.size(), opts.evolution.threads, [&](size_t k) {
    const TriangleMesh& a = *surfaces[static_cast<size_t>(pairs[k].a)];
    const TriangleMesh& b = *surfaces[static_cast<size_t>(pairs[k].b)];
    res.pairPenetrationMm[k] = std::max(penetrationDepth(a, b), penetrationDepth(b, a));
  });
  res.secondsPerStage["separation"] = since(ts);
  return inside;
}

void rasteriseLabels(SegmentationResult& res, const Scene& scene, const std::vector<std::vector<size_t>>& inside,
                     const Grid& grid) {
  const auto tr = Clock::now();
  res.labels = LabelMap(grid, 0);
  std::vector<uint8_t> claims(grid.voxelCount(), 0);
  for (ObjectKind pass : {ObjectKind::Generic, ObjectKind::Muscle, ObjectKind::Bone})
    for (size_t i = 0; i < res.objects.size(); ++i) {
      if (scene.objects[i].kind != pass) continue;
      std::vector<size_t> computed;  // only without the separation's lists
      if (inside.empty()) computed = insideVoxels(res.objects[i].mesh, grid);
      for (size_t v : inside.empty() ? computed : inside[i]) {
        claims[v] = static_cast<uint8_t>(std::min(255, claims[v] + 1));
        res.labels.data[v] = res.objects[i].label;
      }
    }
  for (uint8_t c : claims) res.overlapVoxels += c > 1;
  res.secondsPerStage["rasterise"] += since(tr);
}

}  // namespace msk::detail
