// mskseg segment: the scene's templates evolved into the image; meshes, label map, report and QC pictures.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <thread>

#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/log.h"
#include "msk/imaging/image_export.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/imaging/tet_mesh_io.h"
#include "msk/imaging/transform_io.h"
#include "msk/segmentation/atlas.h"
#include "msk/segmentation/label_tables.h"
#include "msk/segmentation/qc_pictures.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segment_report.h"
#include "msk/segmentation/segmenter.h"
#include "slicer_module.h"

namespace fs = std::filesystem;

namespace msk::cli {
namespace {

/// The image's geometry and how its affine was read.
Json imageJson(const ImageF& image, const NiftiInfo& info) {
  const Grid& g = image.grid;
  Json img;
  img["dims"] = Json::array({g.dims[0], g.dims[1], g.dims[2]});
  img["spacing_mm"] = Json::array({g.spacing[0], g.spacing[1], g.spacing[2]});
  img["affine_source"] = affineSourceName(info.affineSource);
  img["datatype"] = dataTypeName(info.datatype);
  return img;
}

bool isNiftiName(const std::string& path) {
  const auto ends = [&](const std::string& e) {
    return path.size() > e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0;
  };
  return ends(".nii.gz") || ends(".nii");
}

/// The label map on the input's grid and affine, 8-bit when every label fits.
void writeLabelMap(const std::string& path, const LabelMap& labels, const Scene& scene, const NiftiInfo& info) {
  NiftiWriteOptions wo;
  wo.like = &info;
  wo.description = "mskseg segment";
  int maxLabel = 0;
  for (const auto& o : scene.objects) maxLabel = std::max(maxLabel, o.label);
  writeNifti(path, labels, maxLabel <= 255 ? DataType::UInt8 : DataType::Int16, wo);
}

/// Writes every output into `dir`: a mesh per object (and its tet mesh when valid), the label map, the QC pictures,
/// and report.json (the run's report with the command, inputs and the files written).
void writeOutputs(const std::string& dir, const SegmentationResult& res, const Scene& scene, const ImageF& image,
                  const NiftiInfo& info, const SegmentOutputs& outputs, const LabelMap* qcReference, Json report) {
  std::vector<QcObject> qc;
  const std::vector<LabelEntry> table = labelEntries(scene);
  Json& objects = report["objects"];
  for (size_t i = 0; i < res.objects.size(); ++i) {
    const ObjectResult& o = res.objects[i];
    writeMesh(fileInFolder(dir, o.name + ".vtk"), o.mesh, outputs.space);
    objects[i]["mesh"] = o.name + ".vtk";
    if (o.selfIntersections > 0)
      log::warn(o.name + ": " + std::to_string(o.selfIntersections) +
                " pairs of faces of its surface cross each other");
    if (o.volumeMesh.tetCount() > 0) {
      // A tet mesh with inverted elements is not written (it would not be a valid volume); the report says so.
      if (o.invertedTets == 0) {
        writeTetMesh(fileInFolder(dir, o.name + ".vtu"), o.volumeMesh, outputs.space);
        objects[i]["volume_model"]["mesh"] = o.name + ".vtu";
      } else {
        log::warn(o.name + ".vtu not written: " + std::to_string(o.invertedTets) + " of " +
                  std::to_string(o.volumeMesh.tetCount()) + " tets of the volume model are inverted");
      }
    }
    qc.push_back({o.name, o.label, i < table.size() ? std::optional(table[i].rgb) : std::nullopt});
  }
  writeLabelMap(dir + "/labels.nii.gz", res.labels, scene, info);
  NiftiWriteOptions wo;
  wo.like = &info;
  writeLabelTables(dir, table);
  if (outputs.imageExport == "vti") {
    writeVtkImage(dir + "/image.vti", image, outputs.space);
    writeVtkImage(dir + "/labels.vti", res.labels, outputs.space);
  }
  if (outputs.split) {  // one mask per structure, named after it
    fs::create_directories(dir + "/labels");
    for (const ObjectResult& o : res.objects) {
      LabelMap mask = res.labels;
      for (int32_t& v : mask.data) v = v == o.label ? 1 : 0;
      NiftiWriteOptions mo = wo;
      mo.description = "mskseg segment: " + o.name;
      writeNifti(fileInFolder(dir + "/labels", o.name + ".nii.gz"), mask, DataType::UInt8, mo);
    }
  }
  const Json statistics = structureStatistics(image, res);
  writeJsonFile(dir + "/statistics.json", statistics);
  writeAtomically(dir + "/statistics.csv", [&](const std::string& tmp) {
    std::ofstream f(tmp);
    f << statisticsCsv(statistics);
    if (!f.flush()) throw IoError(dir + "/statistics.csv", "cannot write");
  });
  if (outputs.qcPictures) {
    fs::create_directories(dir + "/qc");
    writeQcPictures(dir + "/qc", image, res.labels, qc, qcReference);
    QcMosaicOptions mosaic;
    const fs::path imageFile = fs::absolute(info.path).lexically_normal();  // "<its folder>/<its name>"
    mosaic.title = (imageFile.parent_path().filename() / imageFile.filename()).string();
    writeQcMosaic(dir + "/qc/mosaic.png", image, res.labels, qc, qcReference, mosaic);
  }
  writeJsonFile(dir + "/report.json", report);
}

/// The atlas's global placement as a 3D Slicer transform (applied to the atlas in Slicer, it moves it onto the image).
void writePlacementTransform(const std::string& dir, const Placement& placement) {
  writeSlicerTransform(dir + "/placement.tfm", placement.global);
}

/// A warning for every object whose quality is not ok (its reasons), and one for the case.
void warnQuality(const SegmentationResult& res) {
  if (res.status == QualityStatus::Ok) return;
  int flagged = 0;
  for (const ObjectResult& o : res.objects) {
    if (o.quality.status == QualityStatus::Ok) continue;
    ++flagged;
    std::string why;
    for (const std::string& r : o.quality.reasons) why += (why.empty() ? "" : "; ") + r;
    log::warn(o.name + ": segmentation " + qualityStatusName(o.quality.status) + " (" + why + ")");
  }
  log::warn(std::string("case: segmentation ") + qualityStatusName(res.status) + " (" + std::to_string(flagged) +
            " of " + std::to_string(res.objects.size()) +
            " object(s) not ok; the outputs are written, see report.json objects[].quality)");
}

/// Seconds with two decimals.
std::string secs(double s) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f s", s);
  return b;
}

/// The run's summary on stdout.
void printSummary(const SegmentationResult& res, const Scene& scene, const std::string& out) {
  std::cout << "segmented " << res.objects.size() << " object(s) in " << secs(res.seconds) << " -> " << out
            << ", status " << qualityStatusName(res.status) << "\n";
  double projection = 0;
  for (const auto& kv : res.secondsPerFamily) projection += kv.second;
  std::cout << "  evolution " << secs(res.secondsPerStage.at("evolution")) << ", of which constraint projection "
            << secs(projection) << " for all objects together (report.json timing)\n";
  if (scene.objects.size() > 1)
    std::cout << "  voxels inside two objects: " << res.overlapVoxels
              << (res.collisionSetsBuilt > 0 ? "" : " (no collision response: no pairs declared or --no-collisions)")
              << "\n";
  if (!res.pairPenetrationMm.empty())
    std::cout << "  deepest penetration between collision partners: "
              << *std::max_element(res.pairPenetrationMm.begin(), res.pairPenetrationMm.end()) << " mm\n";
  for (const auto& o : res.objects) {
    int steps = 0;
    for (const auto& l : o.levels) steps += l.steps;
    std::cout << "  " << o.name << ": " << steps << " steps, " << o.mesh.vertexCount() << " vertices, image search "
              << secs(o.imageSearchSeconds) << ", volume " << o.volumeMm3 / 1000.0 << " mL (template "
              << o.templateVolumeMm3 / 1000.0 << " mL), mean residual " << o.meanImageResidualMm << " mm, "
              << qualityStatusName(o.quality.status) << "\n";
  }
}

/// Every object's surface in one mesh, point data "label" holding the object's label (and the arrays all share).
TriangleMesh allSurfaces(const SegmentationResult& res) {
  TriangleMesh all;
  int nv = 0, nf = 0;
  for (const ObjectResult& o : res.objects) {
    nv += o.mesh.vertexCount();
    nf += o.mesh.faceCount();
  }
  all.vertices.resize(nv, 3);
  all.faces.resize(nf, 3);
  Eigen::VectorXd label(nv);
  std::map<std::string, Eigen::VectorXd> data;
  for (const auto& kv : res.objects.front().mesh.pointData) data[kv.first].resize(nv);
  int v = 0, f = 0;
  for (const ObjectResult& o : res.objects) {
    const int n = o.mesh.vertexCount();
    all.vertices.middleRows(v, n) = o.mesh.vertices;
    all.faces.middleRows(f, o.mesh.faceCount()) = o.mesh.faces.array() + v;
    label.segment(v, n).setConstant(o.label);
    for (auto it = data.begin(); it != data.end();) {
      const auto own = o.mesh.pointData.find(it->first);
      if (own == o.mesh.pointData.end()) {
        it = data.erase(it);
      } else {
        it->second.segment(v, n) = own->second;
        ++it;
      }
    }
    v += n;
    f += o.mesh.faceCount();
  }
  all.pointData = std::move(data);
  all.pointData["label"] = label;
  return all;
}

/// The module's parameters: the options 3D Slicer's panel shows for `mskseg segment`.
SlicerModule segmentModule() {
  SlicerModule m;
  m.title = "mskseg segment";
  m.description =
      "Segments bones and muscles with deformable simplex meshes: an atlas (mskseg atlas) is placed in the image by "
      "registration, or a scene's templates already in place are evolved; writes the label map and the surfaces.";
  using P = SlicerParameter;
  m.groups.push_back({"Input and output",
                      "The image, the atlas or scene, and where the results go.",
                      false,
                      {P("image", "--image", "Input volume").type("scalar").extensions(".nii.gz"),
                       P("directory", "--atlas", "Atlas folder"),
                       P("file", "--scene", "Scene (instead of an atlas)").extensions(".json"),
                       P("image", "--label-map", "Output label map").output().type("label").extensions(".nii.gz"),
                       P("geometry", "--surfaces", "Output surfaces").output().type("model").extensions(".vtk"),
                       P("directory", "--out", "Folder of all outputs (optional)").output()}});
  m.groups.push_back(
      {"Segmentation",
       "Speed against accuracy, and what is written besides.",
       false,
       {P("string-enumeration", "--quality", "Quality").byDefault("balanced").choices({"fast", "balanced", "accurate"}),
        P("boolean", "--split", "One mask per structure").byDefault("false"),
        P("boolean", "--no-qc", "No QC pictures").byDefault("false"),
        P("integer", "--threads", "Threads (0: all cores)").byDefault("0").range(0, 256, 1)}});
  m.groups.push_back(
      {"Atlas placement",
       "How an atlas is placed in the image.",
       true,
       {P("string-enumeration", "--metric", "Registration metric").byDefault("auto").choices({"auto", "ncc", "mi"}),
        P("file", "--init-transform", "Initial transform").extensions(".tfm,.txt,.json"),
        P("boolean", "--no-register", "No registration").byDefault("false"),
        P("boolean", "--no-object-register", "No per-object registration").byDefault("false"),
        P("string-enumeration", "--starts", "Starts (subjects, turned muscles)")
            .byDefault("each")
            .choices({"each", "reference"}),
        progressTagsParameter()}});
  return m;
}

}  // namespace

int cmdSegment(const std::vector<std::string>& argv) {
  CommandLine app(
      "segment",
      "Evolves each object's template (2-simplex mesh, coarse to fine) under image targets along the normal, its "
      "shape memory and a global shape prior; objects evolve together, and the scene's collision pairs keep their "
      "surfaces apart.");
  std::string imagePath, scenePath, atlasDir, out, metric = "auto", initTransform, labelMapPath, surfacesPath,
                                                   startsName = "each";
  PlacementOptions placing;
  bool noRegister = false, noObjectRegister = false;
  app.add_option("--image", imagePath, "the image (NIfTI)")->required();
  CLI::Option* sceneOpt = app.add_option("--scene", scenePath, "the scene (scene.json), its templates in place");
  CLI::Option* atlasOpt =
      app.add_option("--atlas", atlasDir, "an atlas folder (mskseg atlas), placed in the image by registration");
  sceneOpt->excludes(atlasOpt);
  app.add_option("--metric", metric,
                 "registration metric with --atlas: auto (ncc when the image's modality is the atlas's, else mi), "
                 "ncc or mi")
      ->check(CLI::IsMember({"auto", "ncc", "mi"}));
  app.add_option("--init-transform", initTransform,
                 "with --atlas: the start of the placement, atlas -> subject: a 4x4 RAS matrix (text rows or JSON "
                 "{\"matrix\": ...}) or a 3D Slicer / ITK .tfm (LPS; the transform that moves the atlas onto the "
                 "subject in Slicer); the registration starts there without its search");
  app.add_flag("--no-register", noRegister,
               "with --atlas: no registration at all; the atlas stays where --init-transform (or its own world) puts "
               "it");
  app.add_flag("--no-object-register", noObjectRegister,
               "with --atlas: the global registration only, no registration of each object's neighbourhood");
  app.add_option("--starts", startsName,
                 "with --atlas: each (the default: with an atlas of one subject, a run from its placement, from "
                 "its muscles turned together by -20, -10, +10 and +20 degrees about the long bone they lie on, and "
                 "from every object at the global placement (without its own registration), the run that matched "
                 "the learned appearance best kept whole; with several subjects, a run from each "
                 "subject's templates, then one more with each object from the start that matched it best) or "
                 "reference (one run from the reference's templates as placed)")
      ->check(CLI::IsMember({"each", "reference"}));
  CLI::Option* outOpt =
      app.add_option("--out", out,
                     "output folder, created with its parents (appears whole or not at all; an existing folder gets "
                     "the files added, replacing those of the same name)");
  app.add_option("--label-map", labelMapPath,
                 "also the label map as this NIfTI file (.nii.gz or .nii), e.g. the output of the 3D Slicer module");
  app.add_option("--surfaces", surfacesPath,
                 "also every object's surface in this one mesh file (.vtk .vtp .stl .obj .ply), point data \"label\" "
                 "holding each object's label");
  SegmentOptions opts;
  opts.evolution.threads = 0;  // all cores unless --threads says otherwise
  SegmentOutputs outputs;
  addSegmentOptions(app, opts, outputs);
  addProgressTagsOption(app);
  app.footer(
      "Writes into OUT: <name>.vtk per object (LPS unless --mesh-space ras; <name>.vtu too for a volumetric object; "
      "point data displacement_mm and image_residual_mm), labels.nii.gz (on the input grid with its affine), "
      "report.json (every parameter, version, timings, steps, volumes; with --atlas the placement: transforms, "
      "registration stages and metrics, each object's move), labels.ctbl, labels.itksnap.txt and labels.tsv (names and "
      "colours of the labels for 3D Slicer, ITK-SNAP and BIDS), statistics.json and .csv (per structure: volumes from "
      "labels and mesh, surface area, image mean/median/sd inside, bounding box, centroid), with --split "
      "labels/<name>.nii.gz, with --image-export vti image.vti and labels.vti, qc/<name>_{axial,coronal,sagittal}.png "
      "and qc/mosaic.png "
      "(the whole case: four slices per view, every object's contour, a legend); with --atlas "
      "also placement.tfm, the global placement as a 3D Slicer transform.");
  if (handleSlicerXml(app, argv, segmentModule())) return 0;
  if (!parseArgs(app, argv)) return 0;
  if (!sceneOpt->count() && !atlasOpt->count()) throw UsageError("give --scene or --atlas");
  if (!outOpt->count() && labelMapPath.empty() && surfacesPath.empty())
    throw UsageError("give --out (or --label-map or --surfaces)");
  if (!labelMapPath.empty() && !isNiftiName(labelMapPath))
    throw UsageError("--label-map '" + labelMapPath + "': use a .nii.gz or .nii name");
  if (!surfacesPath.empty()) requireMeshOutput(surfacesPath);
  if (!atlasOpt->count() &&
      (noRegister || noObjectRegister || metric != "auto" || !initTransform.empty() || startsName != "each"))
    throw UsageError("--metric, --init-transform, --no-register, --no-object-register and --starts need --atlas");
  checkSegmentOptions(opts);
  if (opts.evolution.threads == 0)  // the report names the number used
    opts.evolution.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (!out.empty()) checkOutputFolder(out);
  if (!labelMapPath.empty()) checkOutputFile(labelMapPath);
  if (!surfacesPath.empty()) checkOutputFile(surfacesPath);

  NiftiInfo info;
  const ImageF image = readNifti<float>(imagePath, &info);
  if (const std::string problem = imageProblem(image); !problem.empty()) throw IoError(imagePath, problem);
  std::optional<LabelMap> qcReference;
  if (!outputs.qcReference.empty() && outputs.qcPictures) {
    qcReference = readNifti<int32_t>(outputs.qcReference);  // drawn where it lies in world space, any grid
  }
  Scene scene;
  std::optional<AtlasSegmentation> fromAtlas;  // its scene and result are moved out; its placement stays
  SegmentationResult res;
  if (atlasOpt->count()) {
    if (!initTransform.empty()) placing.start = readLinearTransform(initTransform);
    const Atlas atlas = loadAtlas(atlasDir);
    placing.registration = !noRegister;
    placing.perObject = !noObjectRegister;
    placing.metric = parseRegistrationMetric(metric);
    placing.threads = 0;
    fromAtlas = segmentWithAtlas(
        atlas, image, placing, opts, startsName == "reference" ? AtlasStarts::Reference : AtlasStarts::Each,
        stderrProgress("segment"), [&](Scene& placed) {
          if (const std::string problem = coverageProblem(image.grid, placed); !problem.empty())
            throw IoError(imagePath, problem);
        });
    scene = std::move(fromAtlas->scene);
    res = std::move(fromAtlas->result);
  } else {
    scene = loadScene(scenePath);
    if (const std::string problem = coverageProblem(image.grid, scene); !problem.empty())
      throw IoError(imagePath, problem);
    res = segmentScene(image, scene, opts, stderrProgress("segment"));
  }

  Json report;
  report["mskseg_version"] = MSK_VERSION;
  report["command"] = commandLineJson("segment", argv);
  report["image"] = fs::absolute(imagePath).string();
  if (fromAtlas) {
    report["atlas"] = fs::absolute(atlasDir).string();
    report["placement"] = placementJson(fromAtlas->placement);
    if (fromAtlas->starts.size() > 1) report["placement"]["starts"] = atlasStartsJson(*fromAtlas, scene);
    if (!initTransform.empty()) report["placement"]["init_transform"] = fs::absolute(initTransform).string();
  } else {
    report["scene"] = fs::absolute(scenePath).string();
  }
  report["image_info"] = imageJson(image, info);
  report["mesh_space"] = meshSpaceName(outputs.space);
  report.update(segmentReport(res, scene, opts));
  if (!out.empty())
    writeFolderAtomically(out, [&](const std::string& dir) {
      writeOutputs(dir, res, scene, image, info, outputs, qcReference ? &*qcReference : nullptr, report);
      if (fromAtlas) writePlacementTransform(dir, fromAtlas->placement);
    });
  if (!labelMapPath.empty())
    writeFileWithParents(labelMapPath, [&] { writeLabelMap(labelMapPath, res.labels, scene, info); });
  if (!surfacesPath.empty())
    writeFileWithParents(surfacesPath, [&] { writeMesh(surfacesPath, allSurfaces(res), outputs.space); });
  warnQuality(res);
  printSummary(res, scene, out.empty() ? (labelMapPath.empty() ? surfacesPath : labelMapPath) : out);
  return 0;
}

}  // namespace msk::cli
