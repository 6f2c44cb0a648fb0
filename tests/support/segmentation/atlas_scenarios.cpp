#include "msk/test/atlas_scenarios.h"

#include <Eigen/Geometry>
#include <chrono>
#include <filesystem>

#include "msk/imaging/nifti_io.h"
#include "msk/imaging/rasterize.h"
#include "msk/phantom/phantom.h"
#include "msk/test/volumes.h"

namespace fs = std::filesystem;

namespace msk::test {

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The mirror about the plane x = midX.
Eigen::Matrix4d mirrorX(double midX) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = -1;
  m(0, 3) = 2 * midX;
  return m;
}

/// A real scan's case: the atlas is the scan mirrored about x = midX, the subject the scan moved by `move`.
AtlasCase mirroredScanCase(const std::string& name, const std::string& image, const std::string& labels, double midX,
                           double degrees, double mm, std::vector<AtlasObjectSpec> objects,
                           std::vector<int> reference) {
  AtlasCase c;
  c.name = name;
  c.atlasImage = readNifti<float>(image);
  c.atlasLabels = readNifti<int32_t>(labels);
  const auto bounds = c.atlasImage.grid.worldBounds();
  const Eigen::Matrix4d move = knownMove(degrees, mm, 0.5 * (bounds[0] + bounds[1]));
  c.subject = c.atlasImage;
  c.subjectLabels = c.atlasLabels;
  moveGrid(c.atlasImage.grid, mirrorX(midX));
  moveGrid(c.atlasLabels.grid, mirrorX(midX));
  moveGrid(c.subject.grid, move);
  moveGrid(c.subjectLabels.grid, move);
  c.objects = std::move(objects);
  c.referenceLabel = std::move(reference);
  return c;
}

}  // namespace

void moveGrid(Grid& grid, const Eigen::Matrix4d& m) {
  grid.direction = m.topLeftCorner<3, 3>() * grid.direction;
  grid.origin = m.topLeftCorner<3, 3>() * grid.origin + m.topRightCorner<3, 1>();
}

Eigen::Matrix4d knownMove(double degrees, double mm, const Eigen::Vector3d& centre) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(degrees * M_PI / 180.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r;
  m.topRightCorner<3, 1>() = centre - r * centre + mm * Eigen::Vector3d(2, -1, 1).normalized();
  return m;
}

AtlasCase phantomAtlasCase(uint32_t atlasSeed, uint32_t subjectSeed, const PhantomPose& pose) {
  PhantomOptions a;
  a.seed = atlasSeed;
  PhantomOptions s = a;
  s.seed = subjectSeed;
  s.pose = pose;
  return phantomAtlasCase(a, s);
}

AtlasCase phantomAtlasCase(const std::vector<uint32_t>& atlasSeeds, uint32_t subjectSeed, const PhantomPose& pose) {
  AtlasCase c = phantomAtlasCase(atlasSeeds.at(0), subjectSeed, pose);
  c.name = "phantom seeds";
  for (uint32_t seed : atlasSeeds) c.name += " " + std::to_string(seed);
  c.name += " -> " + std::to_string(subjectSeed);
  for (size_t k = 1; k < atlasSeeds.size(); ++k) {
    PhantomOptions o;
    o.seed = atlasSeeds[k];
    o.meshes = false;
    Phantom p = makePhantom(o);
    c.moreSubjects.emplace_back(std::move(p.image), std::move(p.labels));
  }
  return c;
}

AtlasCase phantomAtlasCase(const PhantomOptions& atlasOptions, const PhantomOptions& subjectOptions) {
  PhantomOptions a = atlasOptions, s = subjectOptions;
  a.meshes = s.meshes = false;
  const Phantom atlas = makePhantom(a);
  const Phantom subject = makePhantom(s);
  AtlasCase c;
  c.name = "phantom seed " + std::to_string(a.seed) + " -> " + std::to_string(s.seed);
  c.atlasImage = atlas.image;
  c.atlasLabels = atlas.labels;
  c.subject = subject.image;
  c.subjectLabels = subject.labels;
  for (const PhantomObject& o : atlas.objects) {
    c.objects.push_back({o.name, o.label, *parseObjectKind(o.kind)});
    c.referenceLabel.push_back(o.label);
  }
  return c;
}

AtlasCase ctAtlasCase(const std::string& sharedData, double degrees, double mm) {
  const std::string dir = sharedData + "/totalseg-ct/";
  if (!fs::exists(dir + "ct.nii.gz")) return {};
  const double midX = labelCentroid(readNifti<int32_t>(dir + "labels.nii.gz"), 25).x();
  AtlasCase c = mirroredScanCase("CT", dir + "ct.nii.gz", dir + "labels.nii.gz", midX, degrees, mm,
                                 {{"femur", 75, ObjectKind::Bone},
                                  {"hip", 77, ObjectKind::Bone},
                                  {"gluteus_maximus", 80, ObjectKind::Muscle},
                                  {"gluteus_medius", 82, ObjectKind::Muscle}},
                                 {76, 78, 81, 83});
  c.options.shape.priorEnd = 0.2;
  c.options.image.rangeFine = 1.0;
  c.options.image.sigmaFine = 1.0;
  c.refineBones = true;
  return c;
}

AtlasCase mrAtlasCase(const std::string& sharedData, double degrees, double mm) {
  const std::string dir = sharedData + "/totalseg-mr/";
  if (!fs::exists(dir + "mr.nii.gz")) return {};
  const double midX = labelCentroid(readNifti<int32_t>(dir + "labels.nii.gz"), 19).x();
  AtlasCase c = mirroredScanCase("MR", dir + "mr.nii.gz", dir + "labels.nii.gz", midX, degrees, mm,
                                 {{"autochthon_right", 46, ObjectKind::Muscle},
                                  {"autochthon_left", 47, ObjectKind::Muscle},
                                  {"vertebrae", 19, ObjectKind::Bone}},
                                 {47, 46, 19});
  c.options.shape.priorEnd = 0.3;
  return c;
}

AtlasRun runAtlasCase(const AtlasCase& c, const std::string& scratch, const PlacementOptions& placing,
                      const AtlasOptions& atlasOptions) {
  AtlasRun run;
  const std::string image = scratch + "/atlas_image.nii.gz", labels = scratch + "/atlas_labels.nii.gz";
  writeNifti(image, c.atlasImage, DataType::Float32);
  writeNifti(labels, c.atlasLabels, DataType::Int16);
  writeNifti(scratch + "/subject_image.nii.gz", c.subject, DataType::Float32);
  writeNifti(scratch + "/subject_labels.nii.gz", c.subjectLabels, DataType::Int16);
  const std::string dir = scratch + "/atlas";
  fs::remove_all(dir);
  fs::create_directories(dir);
  AtlasOptions ao = atlasOptions;
  ao.objects = c.objects;
  for (size_t k = 0; k < c.moreSubjects.size(); ++k) {
    const std::string tag = scratch + "/atlas_subject" + std::to_string(k + 2);
    writeNifti(tag + "_image.nii.gz", c.moreSubjects[k].first, DataType::Float32);
    writeNifti(tag + "_labels.nii.gz", c.moreSubjects[k].second, DataType::Int16);
    ao.moreSubjects.emplace_back(tag + "_image.nii.gz", tag + "_labels.nii.gz");
  }
  auto t0 = std::chrono::steady_clock::now();
  buildAtlas(image, labels, ao, dir);
  const Atlas atlas = loadAtlas(dir);
  run.buildSeconds = since(t0);
  t0 = std::chrono::steady_clock::now();
  const ProgressFn progress = [&run](double f, const std::string&) { run.progress.push_back(f); };
  AtlasSegmentation seg =
      segmentWithAtlas(atlas, c.subject, placing, c.options, c.starts, progress, [&](Scene& placed) {
        for (SceneObject& o : placed.objects)
          if (c.refineBones && o.kind == ObjectKind::Bone) o.model.refine = true;
      });
  const double seconds = since(t0);
  run.placement = std::move(seg.placement);
  run.result = std::move(seg.result);
  run.starts = std::move(seg.starts);
  run.chosen = std::move(seg.chosen);
  const Scene& scene = seg.scene;
  run.placementSeconds = run.placement.seconds;
  run.segmentSeconds = seconds - run.placementSeconds;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    AtlasObjectScore s;
    s.name = scene.objects[i].name;
    const int ref = c.referenceLabel[i];
    s.placed = labelMetrics(rasterize(scene.objects[i].templ, c.subject.grid), 1, c.subjectLabels, ref);
    s.result = labelMetrics(run.result.labels, scene.objects[i].label, c.subjectLabels, ref);
    run.meanAssd += s.result.assd / static_cast<double>(scene.objects.size());
    run.objects.push_back(s);
  }
  return run;
}

}  // namespace msk::test
