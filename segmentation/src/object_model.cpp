// One object's model across levels: its template's resolution levels (remeshed and tetrahedralised where its model
// asks), its polarity, and the constraint sets it gets at each level.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/surface_extraction.h"
#include "msk/segmentation/surface_quality.h"
#include "msk/segmentation/tetrahedralize.h"
#include "parallel_each.h"
#include "segment_stages.h"

namespace msk::detail {

const ImageFeatures& FeatureCache::at(double sigmaMm) {
  const long key = std::lround(sigmaMm * 1000.0);
  auto it = cache_.find(key);
  if (it == cache_.end()) {
    const ImageF& source = normalised();
    const auto t0 = Clock::now();
    it = cache_.emplace(key, featuresOfNormalised(source, sigmaMm)).first;
    seconds_ += since(t0);
  }
  return it->second;
}

const ImageF& FeatureCache::normalised() {
  if (!normalised_) {
    const auto t0 = Clock::now();
    normalised_ = normalisedForFeatures(image_);
    seconds_ += since(t0);
  }
  return *normalised_;
}

void FeatureCache::prepare(const std::vector<double>& sigmasMm, int threads) {
  std::vector<double> missing;
  for (double s : sigmasMm) {
    const long key = std::lround(s * 1000.0);
    if (!cache_.count(key) &&
        std::none_of(missing.begin(), missing.end(), [&](double m) { return std::lround(m * 1000.0) == key; }))
      missing.push_back(s);
  }
  if (missing.empty()) return;
  const ImageF& source = normalised();
  const auto t0 = Clock::now();
  std::vector<ImageFeatures> computed(missing.size());
  parallelEach(missing.size(), threads, [&](size_t k) { computed[k] = featuresOfNormalised(source, missing[k]); });
  for (size_t k = 0; k < missing.size(); ++k) cache_.emplace(std::lround(missing[k] * 1000.0), std::move(computed[k]));
  seconds_ += since(t0);
}

double defaultProximityMm(const SegmentOptions& opts, const Grid& grid) {
  const double run = opts.collision.proximityMm;
  return run > 0 ? run : std::max(1.0, 0.5 * grid.spacing.maxCoeff());
}

std::vector<PairContact> pairContacts(const Scene& scene, const SegmentOptions& opts, const Grid& grid) {
  const CollisionOptions& c = opts.collision;
  const double proximity = defaultProximityMm(opts, grid);
  std::vector<PairContact> out;
  for (const CollisionPair& p : scene.collisions) {
    PairContact k;
    k.gapMm = p.gapMm >= 0 ? p.gapMm : c.gapMm;
    k.proximityMm = p.proximityMm > 0 ? p.proximityMm : proximity;
    k.friction = p.friction >= 0 ? p.friction : c.friction;
    // Table 4.23: mode and target from the scene; resolution from the scene or the run.
    k.response = CollisionResponse{p.mode, p.target, p.resolution.value_or(c.resolution), c.positionBeyondMm};
    out.push_back(k);
  }
  return out;
}

std::vector<ConstraintSet*> ObjectState::sets() const {
  std::vector<ConstraintSet*> out;
  for (ConstraintSet* c : {static_cast<ConstraintSet*>(targets.get()), static_cast<ConstraintSet*>(internal.get()),
                           static_cast<ConstraintSet*>(prior.get()), static_cast<ConstraintSet*>(radial.get()),
                           static_cast<ConstraintSet*>(centering.get()), static_cast<ConstraintSet*>(volumeSet.get()),
                           static_cast<ConstraintSet*>(volumeHold.get())})
    if (c) out.push_back(c);
  return out;
}

Points ObjectState::bentByStage(const Points& templ) const {
  if (stageAxis.rows() == 0) return templ;
  return GeneralisedCylinder(templ, stageAxisRef, attachToAxis(templ, stageAxisRef)).surface(stageAxis);
}

}  // namespace msk::detail

namespace msk {

bool remeshesTemplate(const SceneObject& obj, const SegmentOptions& opts) {
  return obj.model.remesh.value_or(opts.surface.remeshTemplates && obj.kind != ObjectKind::Bone &&
                                   !isotropicTriangulation(obj.templ)) &&
         !obj.model.volumetric;
}

TriangleMesh remeshedTemplate(const SceneObject& obj, MeshCache* cache) {
  const int count = obj.templ.vertexCount();
  const auto derive = [&] { return remeshIsotropic(obj.templ, count); };
  return cache ? cache->get("remeshIsotropic " + std::to_string(count), obj.templ, derive) : derive();
}

}  // namespace msk

namespace msk::detail {

void prepareObject(ObjectState& st, const SegmentOptions& opts, const ResolvedSettings& rs, FeatureCache& features,
                   MeshCache* templateCache) {
  const SceneObject& obj = *st.obj;
  // A mesh derived from another, through the template cache where the run has one.
  const auto derived = [templateCache](const std::string& op, const TriangleMesh& input,
                                       const std::function<TriangleMesh()>& derive) {
    return templateCache ? templateCache->get(op, input, derive) : derive();
  };
  st.out.name = obj.name;
  st.out.label = obj.label;
  st.out.templateVolumeMm3 = enclosedVolume(obj.templ);
  st.out.templateVertices = obj.templ.vertexCount();
  // Unless its model says: bones keep their template's triangulation (a bone template made by decimation puts its
  // vertices where the surface bends, condyles and head, which a uniform remesh spreads out: phantom femurs 0.01–0.06
  // mm more ASSD; they showed no fold without it), muscles and generic objects take the run's, unless their template
  // is already isotropic (remeshed when it was made, as the phantom's are: remeshing it again would only move its
  // vertices). A volumetric object's surface is its tetrahedralisation's boundary, which the mesher makes of
  // well-shaped facets anyway.
  st.out.remeshed = remeshesTemplate(obj, opts);
  const TriangleMesh templ = st.out.remeshed ? remeshedTemplate(obj, templateCache) : obj.templ;
  // Resolution levels of the template: index 0 finest; each coarser level has about a quarter of the vertices.
  st.lv.resize(static_cast<size_t>(rs.levels));
  st.lv[0].triangles = templ;
  TetMesh tets;
  if (obj.model.volumetric) {
    // Tetrahedra about as large as the template's triangles, each with a node off the surface so that finishObject()
    // can untangle any tet the surface folds; the finest surface becomes the tet mesh's boundary.
    tets = tetrahedralize(templ, volumeModelTetOptions(templ));
    st.volume = volumeSimplexFromTets(tets);
    st.lv[0].triangles = tetBoundary(tets);
  }
  for (int l = 1; l < rs.levels; ++l) {
    const int target = std::max(150, st.lv[l - 1].triangles.vertexCount() / 4);
    const TriangleMesh& finer = st.lv[l - 1].triangles;
    st.lv[l].triangles = target < finer.vertexCount() ? derived("decimateMesh " + std::to_string(target), finer,
                                                                [&] { return decimateMesh(finer, target); })
                                                      : finer;
  }
  for (auto& l : st.lv) l.simplex = simplexFromTriangles(l.triangles);
  if (st.volume) {
    // The surface's simplex vertices must be the model's ghosts, in the same order and place.
    const Points& ghosts = st.volume->boundary.positions;
    if (ghosts.rows() != st.lv[0].simplex.vertexCount() ||
        (ghosts - st.lv[0].simplex.positions).cwiseAbs().maxCoeff() > 1e-6 * (1.0 + ghosts.cwiseAbs().maxCoeff()))
      throw Error(obj.name + ": the volume model's boundary does not match its surface model");
  }
  // The profile force needs somewhere to learn its profiles other than the template where it starts: learned there,
  // the profiles hold every vertex in place (the targets are the vertices) and the run ends having changed nothing.
  const TargetMode asked = obj.hasForce ? obj.force : obj.model.imageForce;
  st.force = asked == TargetMode::Profile && !hasProfileSource(obj) ? TargetMode::Gradient : asked;
  if (st.force != asked)
    st.warnings.push_back(
        obj.name +
        ": the profile force has no \"profiles_from\" (a mirror, matrix or image to learn its profiles on); "
        "profiles learned on the template where it starts would hold it there: using the gradient force");
  st.out.force = st.force;
  st.search.mode = st.force;
  st.search.distancePenalty = opts.image.edgePenalty;
  // Polarity: the object's setting, else estimated once on the coarsest scale at the template position, on the template
  // as given (a vote over its vertices: remeshed, the same surface votes with other weights, and a borderline case such
  // as the phantom femur's thin cortex over bright marrow would flip).
  // An object that learns its profiles on an image of its own (an atlas's reference) judges its polarity there, where
  // its template lies on the boundary it was made from.
  st.polarity = obj.hasPolarity ? obj.polarity : Polarity::Auto;
  if (st.polarity == Polarity::Auto && !st.subjectFeatures.empty()) {
    // On the first subject of several, where the template fitted onto it lies.
    const SimplexMesh given = simplexFromTriangles(obj.profileSubjects.front().surface);
    st.polarity =
        estimatePolarity(st.subjectFeatures.front()->at(rs.sigmaMm[0]), given.positions, simplexVertexNormals(given));
  } else if (st.polarity == Polarity::Auto) {
    const SimplexMesh given = st.out.remeshed ? simplexFromTriangles(obj.templ) : st.lv[0].simplex;
    Points positions = given.positions, normals = simplexVertexNormals(given);
    if (st.profileFeatures) toProfileSource(obj, positions, normals);
    FeatureCache& cache = st.profileFeatures ? *st.profileFeatures : features;
    st.polarity = estimatePolarity(cache.at(rs.sigmaMm[0]), positions, normals);
  }
  st.out.polarity = st.polarity;
  st.current = st.lv[static_cast<size_t>(rs.levels - 1)].simplex;
}

namespace {

/// The profiles of a level learned on every subject of an atlas of several and averaged: each level vertex is carried
/// onto each subject's surface (its closest point on the template, same barycentric weights on the subject's fitted
/// template; its small offset from the template mapped along), profiles learned there along that surface's normals,
/// and the unit profiles summed per vertex and normalised again (a vertex without a profile on a subject, a zero row,
/// adds nothing).
LearnedProfiles subjectsProfiles(ObjectState& st, const LevelMeshes& level, double sigmaMm, const Grid& grid) {
  const SceneObject& obj = *st.obj;
  const Eigen::Matrix4d p = obj.profileSource.value_or(Eigen::Matrix4d::Identity());
  const Eigen::Matrix3d a = p.topLeftCorner<3, 3>();
  const SurfaceTransfer transfer(obj.templ, level.triangles.vertices);
  const Points offset = (level.triangles.vertices - transfer.apply(obj.templ.vertices)) * a.transpose();
  LearnedProfiles sum;
  for (size_t k = 0; k < obj.profileSubjects.size(); ++k) {
    TriangleMesh there = level.triangles;
    there.vertices = transfer.apply(obj.profileSubjects[k].surface.vertices) + offset;
    if (a.determinant() < 0) flipFaces(there);  // a mirroring map turns the level's outward winding inward there
    const SimplexMesh at = simplexFromTriangles(there);
    const LearnedProfiles lp =
        learnProfiles(st.subjectFeatures[k]->at(sigmaMm), at.positions, simplexVertexNormals(at), st.search, grid);
    if (k == 0)
      sum = lp;
    else
      sum.profiles += lp.profiles;
  }
  for (Eigen::Index v = 0; v < sum.profiles.rows(); ++v) {
    const double norm = sum.profiles.row(v).norm();
    if (norm > 1e-6)
      sum.profiles.row(v) /= norm;
    else
      sum.profiles.row(v).setZero();
  }
  return sum;
}

}  // namespace

void enterLevel(ObjectState& st, int l, int coarsest, const SegmentOptions& opts, const ImageFeatures& feat,
                const Grid& grid, bool refine) {
  const LevelMeshes& ref = st.lv[static_cast<size_t>(l)];
  if (l != coarsest && !refine) {
    // Carry the displacement of the coarser level's surface over to this level's template.
    const LevelMeshes& coarse = st.lv[static_cast<size_t>(l + 1)];
    const TriangleMesh moved = trianglesFromSimplex(st.current);
    const Eigen::MatrixXd disp = moved.vertices - coarse.triangles.vertices;
    SurfaceTransfer transfer(coarse.triangles, ref.triangles.vertices);
    TriangleMesh start = ref.triangles;
    start.vertices += transfer.apply(disp);
    st.current = simplexFromTriangles(start);
  }
  st.search.mode = refine ? TargetMode::Gradient : st.force;
  st.reuse.clear();
  st.search.edgeLevel = std::numeric_limits<double>::quiet_NaN();
  if (st.search.mode == TargetMode::Gradient && (opts.image.edgeLevel || refine)) {
    const SimplexMesh& at = refine ? st.current : ref.simplex;
    st.search.edgeLevel = estimateEdgeLevel(feat, at.positions, simplexVertexNormals(at));
  }
  if (st.search.mode == TargetMode::Profile && !st.subjectFeatures.empty()) {
    st.profiles = subjectsProfiles(st, ref, feat.sigmaMm, grid);
  } else if (st.search.mode == TargetMode::Profile) {
    // Learned where the template came from (e.g. the mirrored contralateral structure) when the scene says so.
    Points positions = ref.simplex.positions, normals = simplexVertexNormals(ref.simplex);
    toProfileSource(*st.obj, positions, normals);
    const ImageFeatures& source = st.profileFeatures ? st.profileFeatures->at(feat.sigmaMm) : feat;
    st.profiles = learnProfiles(source, positions, normals, st.search, grid);
  }
  // Only what the object's model asks for is built.
  const ObjectModel& model = st.obj->model;
  // After the axis-first stage, the template swept by the stage's axis is the object's reference shape (shape memory,
  // global prior, axis and radii): the straight template's similarity prior would otherwise pull the bend back out.
  const SimplexMesh* shape = &ref.simplex;
  SimplexMesh bentShape;
  if (refine) {
    bentShape = st.current;
    shape = &bentShape;
  } else if (st.stageAxis.rows() > 0) {
    bentShape = ref.simplex;
    bentShape.positions = st.bentByStage(ref.simplex.positions);
    shape = &bentShape;
  }
  st.internal.reset();
  if (model.shapeMemory)
    st.internal = std::make_unique<SimplexInternalConstraints>(
        *shape, model.internalStiffness >= 0 ? model.internalStiffness : opts.shape.internalStiffness,
        opts.shape.internalMode == InternalMode::Smoothing ? InternalMode::Smoothing : *model.shapeMemory);
  st.targets = std::make_unique<TargetConstraints>(opts.image.stiffness);
  st.prior.reset();
  if (model.globalPrior)
    st.prior = std::make_unique<ShapeMatchingConstraint>(
        shape->positions, model.priorTransform.value_or(opts.shape.priorTransform), opts.shape.priorStart);
  st.radial.reset();
  st.centering.reset();
  if (model.medialAxis) {
    // The axis of this level's template, its surface vertices attached with their template radii; the axis starts
    // where the best similarity fit of the template onto the current surface puts it.
    MedialAxisOptions mo;
    mo.spacingMm = model.axisSpacingMm > 0 ? model.axisSpacingMm : opts.axis.spacingMm;
    st.axis = buildMedialAxis(refine ? trianglesFromSimplex(st.current) : ref.triangles, mo);
    if (shape != &ref.simplex && !refine) st.axis.curve.positions = st.bentByStage(st.axis.curve.positions);
    st.attachment = attachToAxis(shape->positions, st.axis.curve.positions);
    const Eigen::Matrix4d fit =
        fitTransform(shape->positions, st.current.positions, Eigen::VectorXd::Ones(ref.simplex.vertexCount()),
                     PriorTransform::Similarity);
    st.axisStart = ((st.axis.curve.positions * fit.topLeftCorner<3, 3>().transpose()).rowwise() +
                    fit.topRightCorner<3, 1>().transpose());
  }
  st.volumeSet.reset();
  st.volumeHold.reset();
  if (st.volume && l == 0) {
    // Tet vertices start where the best affine fit of the template surface onto the current one puts them.
    // The refinement pass starts them where the finest level left them.
    if (refine) {
      st.volStart = st.volFinal;
    } else {
      const int nt = st.volume->tetCount();
      const Eigen::Matrix4d fit =
          fitTransform(ref.simplex.positions, st.current.positions, Eigen::VectorXd::Ones(ref.simplex.vertexCount()),
                       PriorTransform::Affine);
      st.volStart = (st.volume->simplex.positions.topRows(nt) * fit.topLeftCorner<3, 3>().transpose()).rowwise() +
                    fit.topRightCorner<3, 1>().transpose();
    }
    const double gamma = model.volumeStiffness >= 0 ? model.volumeStiffness : opts.volume.stiffness;
    st.volumeSet = std::make_unique<VolumeSimplexConstraints>(*st.volume, gamma, VolumeBoundary::SurfaceDriven);
    // The template's volume, held unless the image demands another (volume_preservation.h).
    st.volumeHold = std::make_unique<VolumePreservation>(ref.simplex);
  }
  for (ConstraintSet* c : st.sets()) c->setFirstParticle(st.first);
  if (st.volumeSet) st.volumeSet->setFirstParticle(st.volFirst);  // tets first, then the ghosts = the surface
}

void buildAxisSets(ObjectState& st, const SegmentOptions& opts) {
  const ObjectModel& model = st.obj->model;
  const double gamma = model.radialStiffness >= 0 ? model.radialStiffness : opts.axis.radialStiffness;
  st.radial = std::make_unique<RadialConstraints>(st.attachment, st.axisFirst, gamma);
  st.centering =
      std::make_unique<AxisCentering>(st.attachment, st.axisFirst, st.axis.curve.vertexCount(), opts.axis.centering);
  st.radial->setFirstParticle(st.first);
  st.centering->setFirstParticle(st.first);
}

}  // namespace msk::detail
