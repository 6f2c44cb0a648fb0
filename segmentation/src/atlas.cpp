#include "msk/segmentation/atlas.h"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <set>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/winding_number.h"
#include "msk/imaging/checksum.h"
#include "msk/imaging/filters.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/mesh_cache.h"
#include "msk/segmentation/surface_fit.h"
#include "msk/segmentation/surface_quality.h"
#include "parallel_each.h"

namespace fs = std::filesystem;

namespace msk {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

const char* kFormat = "mskseg-atlas";
const char* kReference = "reference.nii.gz";
const char* kScene = "scene.json";

/// Display colours of an atlas's objects in order (RGB 0..255), bones first in a bone colour.
Json objectColour(ObjectKind kind, size_t index) {
  static const int muscles[][3] = {{192, 104, 88}, {221, 130, 101}, {183, 69, 56}, {240, 160, 120},
                                   {160, 80, 110}, {200, 120, 150}, {150, 60, 40}, {230, 100, 80}};
  if (kind == ObjectKind::Bone) return Json::array({241, 214, 145});
  const int* c = muscles[index % 8];
  return Json::array({c[0], c[1], c[2]});
}

Json matrixJson(const Eigen::Matrix4d& m) {
  Json rows = Json::array();
  for (int r = 0; r < 4; ++r) rows.push_back(Json::array({m(r, 0), m(r, 1), m(r, 2), m(r, 3)}));
  return rows;
}

/// The template's axis-aligned box, RAS mm.
std::array<Eigen::Vector3d, 2> meshBox(const TriangleMesh& m) {
  return {m.vertices.colwise().minCoeff().transpose(), m.vertices.colwise().maxCoeff().transpose()};
}
}  // namespace

std::vector<AtlasObjectSpec> parseAtlasObjects(const std::string& text, const std::string& option) {
  std::vector<AtlasObjectSpec> out;
  std::set<std::string> names;
  std::set<int> labels;
  size_t begin = 0;
  while (begin <= text.size()) {
    const size_t end = std::min(text.find(',', begin), text.size());
    const std::string entry = text.substr(begin, end - begin);
    begin = end + 1;
    std::vector<std::string> parts;
    for (size_t b = 0;;) {
      const size_t e = entry.find(':', b);
      parts.push_back(entry.substr(b, e == std::string::npos ? std::string::npos : e - b));
      if (e == std::string::npos) break;
      b = e + 1;
    }
    if (parts.size() < 2 || parts.size() > 3)
      throw ParameterError(option, entry, "each entry must be NAME:LABEL or NAME:LABEL:KIND");
    AtlasObjectSpec spec;
    spec.name = parts[0];
    if (!isSafeName(spec.name))
      throw ParameterError(option, entry,
                           "names are 1-64 characters of letters, digits, '_', '.', '-', starting with a letter or "
                           "digit");
    char* stop = nullptr;
    const long label = std::strtol(parts[1].c_str(), &stop, 10);
    if (parts[1].empty() || *stop != '\0' || label < 1 || label > 32767)
      throw ParameterError(option, entry, "the label must be an integer in 1..32767");
    spec.label = static_cast<int>(label);
    if (parts.size() == 3) {
      const std::optional<ObjectKind> kind = parseObjectKind(parts[2]);
      if (!kind) throw ParameterError(option, entry, "the kind must be bone, muscle or generic");
      spec.kind = *kind;
    }
    if (!names.insert(spec.name).second) throw ParameterError(option, entry, "duplicate name " + spec.name);
    if (!labels.insert(spec.label).second)
      throw ParameterError(option, entry, "duplicate label " + std::to_string(spec.label));
    out.push_back(spec);
    if (end == text.size()) break;
  }
  return out;
}

namespace {

/// A subject's image and labels, read and checked: no NaN or constant image, labels on the image's grid.
std::pair<ImageF, LabelMap> readSubject(const std::string& imagePath, const std::string& labelsPath) {
  ImageF image = readNifti<float>(imagePath);
  if (const std::string problem = imageProblem(image); !problem.empty()) throw IoError(imagePath, problem);
  LabelMap labels = readNifti<int32_t>(labelsPath);
  if (!labels.grid.sameGeometry(image.grid, 1e-3))
    throw IoError(labelsPath, "not on the grid of " + imagePath + " (dimensions or affine differ)");
  return {std::move(image), std::move(labels)};
}

/// atlas.json's entry for a source subject: its files and their checksums.
Json sourceJson(const std::string& imagePath, const std::string& labelsPath) {
  return {{"image", fs::absolute(imagePath).string()},
          {"image_sha256", sha256File(imagePath)},
          {"labels", fs::absolute(labelsPath).string()},
          {"labels_sha256", sha256File(labelsPath)}};
}

/// The template options for an object of `kind`: only bones are continued beyond the scan's edge
/// (AtlasOptions::templates).
TemplateOptions templateOptionsFor(const AtlasOptions& opts, ObjectKind kind) {
  TemplateOptions to = opts.templates;
  if (kind != ObjectKind::Bone) to.extendCutMm = 0;
  return to;
}

bool meanShapeOf(AtlasShape shape, ObjectKind kind) {
  return shape == AtlasShape::Mean || (shape == AtlasShape::Auto && kind == ObjectKind::Bone);
}

/// The further subjects of an atlas: each registered to the reference (affine, from the reference's crop), each
/// object's reference template fitted onto its structure there, its image cropped and written (subject_<k>.nii.gz) with
/// the fitted templates (subject_<k>_<name>.vtk; the reference's own as subject_1_<name>.vtk); the objects learn their
/// profiles on every subject, and the templates meanShapeOf() names become the mean of the fitted ones laid back onto
/// the reference (opts.shape). `objects` (atlas.json's entries) gets each subject's fit figures, `sources` each
/// subject.
void addSubjects(const AtlasOptions& opts, const std::string& modality, const ImageF& reference, Scene& scene,
                 Json& objects, Json& sources, std::vector<std::string>& files, const std::string& dir,
                 const ProgressFn& progress) {
  const size_t n = scene.objects.size(), subjects = opts.moreSubjects.size() + 1;
  std::vector<Points> sum(n);
  for (size_t i = 0; i < n; ++i) {
    SceneObject& obj = scene.objects[i];
    sum[i] = obj.templ.vertices;
    SceneObject::Subject own;
    own.imagePath = dir + "/" + kReference;
    own.surfacePath = fileInFolder(dir, "subject_1_" + obj.name + ".vtk");
    own.surface = obj.templ;
    writeMesh(own.surfacePath, own.surface, MeshSpace::LPS);
    files.push_back(fs::path(own.surfacePath).filename().string());
    obj.profileSubjects.push_back(own);
    objects[i]["subjects"] = Json::array({{{"subject", 1}, {"fit", "the reference: its own template"}}});
  }
  for (size_t k = 0; k < opts.moreSubjects.size(); ++k) {
    const auto& [imagePath, labelsPath] = opts.moreSubjects[k];
    const std::string tag = "subject_" + std::to_string(k + 2);
    if (progress) progress(static_cast<double>(k + 1) / static_cast<double>(subjects), tag + " registration");
    const auto [image, labels] = readSubject(imagePath, labelsPath);
    RegistrationOptions ro;
    ro.threads = opts.threads;
    ro.metric = guessModality(image) == modality ? RegistrationMetric::Ncc : RegistrationMetric::MattesMi;
    const RegistrationResult reg = registerImages(reference, image, ro);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
    std::vector<TriangleMesh> fitted(n);
    for (size_t i = 0; i < n; ++i) {
      SceneObject& obj = scene.objects[i];
      if (progress)
        progress((static_cast<double>(k + 1) + static_cast<double>(i + 1) / static_cast<double>(n + 1)) /
                     static_cast<double>(subjects),
                 tag + " " + obj.name);
      TriangleMesh target;
      try {
        target = templateFromLabels(labels, obj.label, templateOptionsFor(opts, obj.kind));
      } catch (const Error& e) {
        throw IoError(labelsPath, "label " + std::to_string(obj.label) + " (" + obj.name + "): " + e.what());
      }
      TriangleMesh moving = obj.templ;
      transformMesh(moving, reg.transform);
      SurfaceFitReport fr;
      fitted[i] = fitSurface(moving, target, {}, &fr);
      if (enclosedVolume(fitted[i]) < 0) flipFaces(fitted[i]);  // a mirroring registration turned it inward
      const auto box = meshBox(fitted[i]);
      lo = lo.cwiseMin(box[0]);
      hi = hi.cwiseMax(box[1]);

      objects[i]["subjects"].push_back({{"subject", k + 2},
                                        {"fit_mean_mm", fr.meanDistanceMm},
                                        {"fit_max_mm", fr.maxDistanceMm},
                                        {"fit_reverse_mean_mm", fr.meanReverseDistanceMm},
                                        {"fit_volume_ratio", fr.volumeRatio},
                                        {"fit_self_intersections", fr.selfIntersections},
                                        {"volume_ml", enclosedVolume(target) / 1000.0}});
      if (fr.meanDistanceMm > 1.0 || fr.meanReverseDistanceMm > 1.5 || std::abs(fr.volumeRatio - 1) > 0.1)
        log::warn(obj.name + ": the template fitted onto " + labelsPath + " stays " +
                  std::to_string(fr.meanDistanceMm) + " mm (mean) from its surface there, volume ratio " +
                  std::to_string(fr.volumeRatio) + ": check that subject's labels and registration");
    }
    // Back in the reference's world by the one similarity that best lays all of the subject's fitted templates onto
    // the reference's own, vertex for vertex (Procrustes): the mean is of the subjects' anatomy, not of where each
    // subject's image registration left it (a round thigh's turn about its axis is poorly fixed by the whole image),
    // and one map for all objects keeps them side by side as they are in the subject.
    Eigen::Index total = 0;
    for (size_t i = 0; i < n; ++i) total += fitted[i].vertices.rows();
    Eigen::Matrix3Xd from(3, total), to(3, total);
    for (size_t i = 0, at = 0; i < n; at += static_cast<size_t>(fitted[i].vertices.rows()), ++i) {
      from.middleCols(static_cast<Eigen::Index>(at), fitted[i].vertices.rows()) = fitted[i].vertices.transpose();
      to.middleCols(static_cast<Eigen::Index>(at), fitted[i].vertices.rows()) =
          scene.objects[i].templ.vertices.transpose();
    }
    const Eigen::Matrix4d onto = Eigen::umeyama(from, to, true);
    for (size_t i = 0; i < n; ++i) {
      TriangleMesh home = fitted[i];
      transformMesh(home, onto);
      sum[i] += home.vertices;
    }
    const Eigen::Vector3d margin = Eigen::Vector3d::Constant(opts.marginMm);
    NiftiWriteOptions wo;
    wo.description = "mskseg atlas subject";
    writeNifti(dir + "/" + tag + ".nii.gz", cropToWorldBox(image, lo - margin, hi + margin), DataType::Float32, wo);
    files.push_back(tag + ".nii.gz");
    for (size_t i = 0; i < n; ++i) {
      SceneObject::Subject s;
      s.imagePath = dir + "/" + tag + ".nii.gz";
      s.surfacePath = fileInFolder(dir, tag + "_" + scene.objects[i].name + ".vtk");
      s.surface = fitted[i];
      writeMesh(s.surfacePath, s.surface, MeshSpace::LPS);
      files.push_back(fs::path(s.surfacePath).filename().string());
      scene.objects[i].profileSubjects.push_back(std::move(s));
    }
    Json reg_;
    reg_["transform_reference_to_subject"] = matrixJson(reg.transform);
    reg_["metric"] = registrationMetricName(ro.metric);
    reg_["metric_before"] = reg.startMetric;
    reg_["metric_after"] = reg.metric;
    reg_["overlap"] = reg.overlap;
    Json source = sourceJson(imagePath, labelsPath);
    source["stored_as"] = tag + ".nii.gz";
    source["registration"] = reg_;
    sources.push_back(source);
  }
  for (size_t i = 0; i < n; ++i) {
    SceneObject& obj = scene.objects[i];
    if (!meanShapeOf(opts.shape, obj.kind)) continue;
    TriangleMesh mean = obj.templ;
    mean.vertices = sum[i] / static_cast<double>(subjects);
    if (const std::string problem = templateProblem(mean); !problem.empty()) {
      log::warn(obj.name + ": the subjects' mean shape is not a usable surface (" + problem +
                "); its template stays the reference's own");
      continue;
    }
    obj.templ = mean;
  }
}

}  // namespace

Json buildAtlas(const std::string& imagePath, const std::string& labelsPath, const AtlasOptions& opts,
                const std::string& dir, const ProgressFn& progress) {
  if (opts.objects.empty()) throw ParameterError("--objects", "", "name at least one object");
  if (!(opts.marginMm >= 0 && opts.marginMm <= 500))
    throw ParameterError("--margin", std::to_string(opts.marginMm), "must be in [0, 500] mm");
  checkTemplateOptions(opts.templates);
  const auto [image, labels] = readSubject(imagePath, labelsPath);
  std::map<int32_t, size_t> counts;
  for (int32_t v : labels.data) ++counts[v];

  Scene scene;
  Json objects = Json::array();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (size_t i = 0; i < opts.objects.size(); ++i) {
    const AtlasObjectSpec& spec = opts.objects[i];
    if (!counts.count(spec.label))
      throw IoError(labelsPath, "label " + std::to_string(spec.label) + " (" + spec.name + ") not found");
    // The reference's templates are the first of the subjects' equal shares of the work.
    if (progress)
      progress(static_cast<double>(i) / static_cast<double>(opts.objects.size() + 1) /
                   static_cast<double>(opts.moreSubjects.size() + 1),
               spec.name);
    TemplateReport tr;
    SceneObject obj;
    obj.name = spec.name;
    obj.label = spec.label;
    obj.kind = spec.kind;
    obj.templ = templateFromLabels(labels, spec.label, templateOptionsFor(opts, spec.kind), &tr);
    obj.templatePath = fileInFolder(dir, "template_" + spec.name + ".vtk");
    obj.model = defaultModel(spec.kind);
    const Json colour = objectColour(spec.kind, i);
    obj.colour = std::array<int, 3>{colour[0].get<int>(), colour[1].get<int>(), colour[2].get<int>()};
    obj.model.imageForce = TargetMode::Profile;
    obj.hasForce = true;
    obj.force = TargetMode::Profile;
    obj.profileImagePath = dir + "/" + kReference;
    const auto box = meshBox(obj.templ);
    lo = lo.cwiseMin(box[0]);
    hi = hi.cwiseMax(box[1]);
    Json o;
    o["name"] = spec.name;
    o["label"] = spec.label;
    o["kind"] = objectKindName(spec.kind);
    o["colour"] = objectColour(spec.kind, i);
    o["template"] = fs::path(obj.templatePath).filename().string();
    o["template_vertices"] = obj.templ.vertexCount();
    o["label_voxels"] = tr.voxels;
    Json cut = Json::array();
    for (const std::string& face : tr.extendedFaces) cut.push_back(face);
    o["cut_by_field_of_view"] = cut;  // faces the label was cut by, continued beyond by extended_mm
    o["extended_mm"] = tr.extendedMm;
    objects.push_back(o);
    scene.objects.push_back(std::move(obj));
  }
  // The reference image: the templates' box grown by the margin, voxels and affine as read.
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(opts.marginMm);
  const ImageF reference = cropToWorldBox(image, lo - margin, hi + margin);
  const std::string modality = opts.modality.empty() ? guessModality(image) : opts.modality;
  Json sources = Json::array();
  sources.push_back(sourceJson(imagePath, labelsPath));
  std::vector<std::string> extraFiles;
  if (!opts.moreSubjects.empty())
    addSubjects(opts, modality, reference, scene, objects, sources, extraFiles, dir, progress);
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    writeMesh(scene.objects[i].templatePath, scene.objects[i].templ, MeshSpace::LPS);
    objects[i]["template_volume_ml"] = enclosedVolume(scene.objects[i].templ) / 1000.0;
  }
  if (opts.collisions == AtlasCollisions::Auto) scene.autoCollisions = AutoCollisions{};
  if (opts.collisions == AtlasCollisions::All)
    for (int a = 0; a < static_cast<int>(scene.objects.size()); ++a)
      for (int b = a + 1; b < static_cast<int>(scene.objects.size()); ++b) {
        CollisionPair p;
        p.a = a;
        p.b = b;
        scene.collisions.push_back(p);
      }
  scene.description = "atlas from " + fs::path(imagePath).filename().string();
  writeScene(scene, dir + "/" + kScene);

  NiftiWriteOptions wo;
  wo.description = "mskseg atlas reference";
  writeNifti(dir + "/" + kReference, reference, DataType::Float32, wo);

  Json atlas;
  atlas["format"] = kFormat;
  atlas["format_version"] = kAtlasFormatVersion;
  atlas["mskseg_version"] = MSK_VERSION;
  atlas["modality"] = modality;
  Json ref;
  ref["image"] = kReference;
  ref["dims"] = Json::array({reference.grid.dims[0], reference.grid.dims[1], reference.grid.dims[2]});
  ref["spacing_mm"] = Json::array({reference.grid.spacing[0], reference.grid.spacing[1], reference.grid.spacing[2]});
  ref["margin_mm"] = opts.marginMm;
  ref["extend_cut_mm"] = opts.templates.extendCutMm;
  ref["box_ras_mm"] = Json::array({Json::array({lo.x(), lo.y(), lo.z()}), Json::array({hi.x(), hi.y(), hi.z()})});
  atlas["reference"] = ref;
  // Stored as read; both the registration and the profiles normalise every image the same way when they use it.
  Json norm;
  norm["method"] = "robust percentiles: the 1st and 99th percentile of an image's voxels mapped to 0 and 1";
  norm["applied"] = "when used, to the reference and to the subject alike (registration, learned profiles)";
  norm["reference_p1"] = percentile(reference, 1.0);
  norm["reference_p99"] = percentile(reference, 99.0);
  norm["profiles"] = "zero-mean unit-norm, compared by normalised cross-correlation";
  atlas["intensity_normalisation"] = norm;
  for (size_t i = 0; i < scene.objects.size(); ++i)
    objects[i]["shape"] = !opts.moreSubjects.empty() && meanShapeOf(opts.shape, scene.objects[i].kind)
                              ? "the mean of the " + std::to_string(sources.size()) +
                                    " subjects' fitted templates, laid onto the reference by one similarity each"
                              : "the reference's own";
  atlas["objects"] = objects;
  atlas["collisions"] = opts.collisions == AtlasCollisions::Auto  ? "auto"
                        : opts.collisions == AtlasCollisions::All ? "all"
                                                                  : "none";
  atlas["sources"] = sources;  // the reference first
  Json files = Json::object();
  for (const auto& f : {std::string(kReference), std::string(kScene)}) files[f] = sha256File(dir + "/" + f);
  for (const std::string& f : extraFiles) files[f] = sha256File(dir + "/" + f);
  for (const SceneObject& o : scene.objects)
    files[fs::path(o.templatePath).filename().string()] = sha256File(o.templatePath);
  atlas["files_sha256"] = files;
  writeJsonFile(dir + "/atlas.json", atlas);
  if (progress) progress(1.0, "done");
  return atlas;
}

Atlas loadAtlas(const std::string& dir) {
  const std::string metaPath = (fs::path(dir) / "atlas.json").string();
  if (!fs::is_directory(dir)) throw IoError(dir, "not a folder (an atlas is a folder made by mskseg atlas)");
  if (!fs::exists(metaPath)) throw IoError(metaPath, "missing (not an atlas folder made by mskseg atlas)");
  Atlas a;
  a.dir = dir;
  a.meta = readJsonFile(metaPath);
  const Json* format = jsonMember(a.meta, "format");
  if (!format || !format->is_string() || format->get<std::string>() != kFormat)
    throw IoError(metaPath, std::string("\"format\" is not \"") + kFormat + "\"");
  const Json* version = jsonMember(a.meta, "format_version");
  if (!version || !version->is_number_integer() || version->get<int>() > kAtlasFormatVersion ||
      version->get<int>() < kAtlasOldestFormatVersion)
    throw IoError(metaPath, "format version " + (version ? version->dump() : std::string("missing")) +
                                ", this mskseg reads versions " + std::to_string(kAtlasOldestFormatVersion) + " to " +
                                std::to_string(kAtlasFormatVersion));
  const Json* files = jsonMember(a.meta, "files_sha256");
  if (!files || !files->is_object() || !jsonMember(*files, kReference) || !jsonMember(*files, kScene))
    throw IoError(metaPath, "\"files_sha256\" must list reference.nii.gz, scene.json and the templates");
  for (const auto& kv : files->items()) {
    const std::string& name = kv.key();
    if (name.empty() || name.find('/') != std::string::npos || name == "." || name == ".." || !kv.value().is_string())
      throw IoError(metaPath, "\"files_sha256\" entry \"" + name + "\" is not a file name with a checksum");
    const std::string path = (fs::path(dir) / name).string();
    if (!fs::is_regular_file(path)) throw IoError(path, "missing from the atlas (atlas.json lists it)");
    if (sha256File(path) != kv.value().get<std::string>())
      throw IoError(path, "checksum does not match atlas.json (the file changed after the atlas was built)");
  }
  const Json* modality = jsonMember(a.meta, "modality");
  a.modality = modality && modality->is_string() ? modality->get<std::string>() : "mr";
  a.scene = loadScene((fs::path(dir) / kScene).string());
  const Json* objects = jsonMember(a.meta, "objects");
  if (!objects || !objects->is_array() || objects->size() != a.scene.objects.size())
    throw IoError(metaPath, "\"objects\" does not list the objects of scene.json");
  for (const SceneObject& o : a.scene.objects) {
    if (!files->contains(fs::path(o.templatePath).filename().string()) ||
        fs::path(o.templatePath).parent_path().lexically_normal() != fs::path(dir).lexically_normal())
      throw IoError(metaPath, "template of " + o.name + " is not one of the atlas's checked files");
    for (const SceneObject::Subject& sub : o.profileSubjects)
      for (const std::string& f : {sub.imagePath, sub.surfacePath})
        if (!files->contains(fs::path(f).filename().string()) ||
            fs::path(f).parent_path().lexically_normal() != fs::path(dir).lexically_normal())
          throw IoError(metaPath, "subject file " + fs::path(f).filename().string() + " of " + o.name +
                                      " is not one of the atlas's checked files");
    if (o.profileImage) a.reference = o.profileImage;
  }
  if (!a.reference) a.reference = std::make_shared<ImageF>(readNifti<float>((fs::path(dir) / kReference).string()));
  return a;
}

namespace {

/// How deep the surfaces of a scene pair reach into each other: the share of each one's vertices inside the other
/// (winding number), the larger of the two.
double pairOverlap(const TriangleMesh& a, const TriangleMesh& b) {
  auto inside = [](const TriangleMesh& m, const TriangleMesh& by) {
    const WindingNumber w(by.vertices, by.faces);
    int n = 0;
    for (int v = 0; v < m.vertexCount(); ++v) n += w.inside(m.vertices.row(v).transpose()) ? 1 : 0;
    return static_cast<double>(n) / std::max(1, m.vertexCount());
  };
  return std::max(inside(a, b), inside(b, a));
}

TriangleMesh moved(const TriangleMesh& m, const Eigen::Matrix4d& t) {
  TriangleMesh out = m;
  transformMesh(out, t);
  return out;
}

/// The registration of one object's neighbourhood, from `start` (the global placement, or for a muscle the placement
/// of the bone it lies on); kept only under the conditions of placeAtlas(). Its move is measured from `start`.
ObjectPlacement placeObject(const Atlas& atlas, const SceneObject& obj, const ImageF& subject,
                            const Eigen::Matrix4d& start, const RegistrationOptions& base,
                            const PlacementOptions& opts) {
  const auto t0 = Clock::now();
  ObjectPlacement op;
  op.name = obj.name;
  op.transform = start;
  const auto box = meshBox(obj.templ);
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(opts.objectMarginMm);
  const Eigen::Vector3d centre = 0.5 * (box[0] + box[1]);
  try {
    const ImageF neighbourhood = cropToWorldBox(*atlas.reference, box[0] - margin, box[1] + margin);
    RegistrationOptions ro = base;
    ro.model = PriorTransform::Similarity;
    ro.initialise = false;
    const RegistrationResult r = registerImages(neighbourhood, subject, ro, start);
    op.metricBefore = r.startMetric;
    op.metricAfter = r.metric;
    const TransformDifference d = transformDifference(r.transform, start, centre);
    op.moveDegrees = d.degrees;
    op.moveMm = d.mm;
    if (!(r.metric > r.startMetric))
      op.note = "its own registration did not improve its neighbourhood's match";
    else if (d.degrees > kMaxOwnTurnDegrees || d.mm > kMaxOwnMoveMm) {
      op.note = "its own registration moved it too far from its start";
      op.refusedTooFar = true;
    } else {
      op.transform = r.transform;
      op.registered = true;
    }
  } catch (const Error& e) {
    op.note = std::string("its own registration failed: ") + e.what();
  }
  op.seconds = since(t0);
  return op;
}

/// Pulls objects back toward their start placements `start` (their own move halved, up to three times, then undone),
/// the one that moved most first, until no scene pair reaches into each other deeper than under the start placements:
/// the share of either surface's vertices inside the other may grow by at most 0.5 %. Records each pair's figures.
void keepPairsApart(const Atlas& atlas, Placement& p, const std::vector<Eigen::Matrix4d>& start) {
  const Scene& scene = atlas.scene;
  std::vector<Eigen::Matrix4d> own;
  std::vector<double> share(p.objects.size(), 1.0);  // how much of its own move each object keeps
  for (const ObjectPlacement& o : p.objects) own.push_back(o.transform);
  auto placed = [&](size_t i) { return moved(scene.objects[i].templ, p.objects[i].transform); };
  p.pairs.clear();
  for (const CollisionPair& pair : scene.collisions) {
    const size_t ia = static_cast<size_t>(pair.a), ib = static_cast<size_t>(pair.b);
    PairPlacement pp;
    pp.a = scene.objects[ia].name;
    pp.b = scene.objects[ib].name;
    pp.overlapGlobal = pairOverlap(moved(scene.objects[ia].templ, p.global), moved(scene.objects[ib].templ, p.global));
    const bool fromGlobal = start[ia] == p.global && start[ib] == p.global;
    const double allowed = (fromGlobal ? pp.overlapGlobal
                                       : pairOverlap(moved(scene.objects[ia].templ, start[ia]),
                                                     moved(scene.objects[ib].templ, start[ib]))) +
                           0.005;
    pp.overlapPlaced = pairOverlap(placed(ia), placed(ib));
    while (pp.overlapPlaced > allowed && (p.objects[ia].registered || p.objects[ib].registered)) {
      const bool pickA =
          p.objects[ia].registered &&
          (!p.objects[ib].registered || share[ia] * p.objects[ia].moveMm >= share[ib] * p.objects[ib].moveMm);
      const size_t i = pickA ? ia : ib;
      ObjectPlacement& o = p.objects[i];
      share[i] = share[i] > 0.2 ? 0.5 * share[i] : 0.0;
      o.transform = start[i] + share[i] * (own[i] - start[i]);
      if (share[i] == 0.0) {
        o.registered = false;
        o.note = "its own registration brought it into a collision partner";
        o.keptOutOfPartner = true;
      } else {
        o.note = "its own move was scaled by " + std::to_string(share[i]) + " to keep out of a collision partner";
      }
      pp.overlapPlaced = pairOverlap(placed(ia), placed(ib));
    }
    p.pairs.push_back(pp);
  }
}

/// The start of each object's own registration: the global placement, but for a muscle whose one bone partner's own
/// registration was kept, that bone's placement (the muscles on a bone turn with it, as a limb turns about its bone).
/// Muscles carried by a bone keep their places relative to one another; a muscle that a bone's placement would push
/// into a partner deeper than the global placement does starts from the global placement.
std::vector<Eigen::Matrix4d> startPlacements(const Atlas& atlas, Placement& p) {
  const Scene& scene = atlas.scene;
  const size_t n = scene.objects.size();
  std::vector<Eigen::Matrix4d> start(n, p.global);
  for (size_t i = 0; i < n; ++i) {
    if (scene.objects[i].kind != ObjectKind::Muscle) continue;
    std::vector<size_t> bones;
    for (const CollisionPair& pair : scene.collisions) {
      const size_t other = pair.a == static_cast<int>(i)   ? static_cast<size_t>(pair.b)
                           : pair.b == static_cast<int>(i) ? static_cast<size_t>(pair.a)
                                                           : n;
      if (other < n && scene.objects[other].kind == ObjectKind::Bone) bones.push_back(other);
    }
    if (bones.size() == 1 && p.objects[bones[0]].registered) {
      start[i] = p.objects[bones[0]].transform;
      p.objects[i].carriedBy = scene.objects[bones[0]].name;
    }
  }
  // Bones are where their own registrations put them, the others at their starts. A carried muscle in a pair that
  // reaches deeper than under the global placement goes back to it, until no pair does (each muscle at most once).
  auto at = [&](size_t i) {
    return moved(scene.objects[i].templ, scene.objects[i].kind == ObjectKind::Bone ? p.objects[i].transform : start[i]);
  };
  for (bool changed = true; changed;) {
    changed = false;
    for (const CollisionPair& pair : scene.collisions) {
      const size_t ia = static_cast<size_t>(pair.a), ib = static_cast<size_t>(pair.b);
      if (p.objects[ia].carriedBy.empty() && p.objects[ib].carriedBy.empty()) continue;
      const double global =
          pairOverlap(moved(scene.objects[ia].templ, p.global), moved(scene.objects[ib].templ, p.global));
      if (pairOverlap(at(ia), at(ib)) <= global + 0.005) continue;
      for (size_t i : {ia, ib})
        if (!p.objects[i].carriedBy.empty()) {
          start[i] = p.global;
          p.objects[i].carriedBy.clear();
          changed = true;
        }
    }
  }
  return start;
}

}  // namespace

Placement placeAtlas(const Atlas& atlas, const ImageF& subject, const PlacementOptions& opts,
                     const ProgressFn& progress) {
  const auto t0 = Clock::now();
  Placement p;
  p.global = opts.start.value_or(Eigen::Matrix4d::Identity());
  RegistrationOptions ro;
  ro.threads = opts.threads;
  ro.metric = opts.metric.value_or(guessModality(subject) == atlas.modality ? RegistrationMetric::Ncc
                                                                            : RegistrationMetric::MattesMi);
  if (opts.registration) {
    p.metric = registrationMetricName(ro.metric);
    RegistrationOptions global = ro;
    global.model = PriorTransform::Affine;
    global.initialise = !opts.start.has_value();
    if (progress) progress(0.0, "global registration");
    p.registration = registerImages(*atlas.reference, subject, global, p.global);
    p.global = p.registration->transform;
  }
  // Bones first, each from the global placement; then the other objects, each from its start (startPlacements()).
  const size_t n = atlas.scene.objects.size();
  p.objects.resize(n);
  int done = 0;
  auto place = [&](size_t i, const Eigen::Matrix4d& start) {
    const SceneObject& obj = atlas.scene.objects[i];
    if (progress) progress(0.5 + 0.5 * static_cast<double>(done++) / static_cast<double>(n), obj.name);
    if (opts.registration && opts.perObject) {
      const std::string carriedBy = p.objects[i].carriedBy;
      p.objects[i] = placeObject(atlas, obj, subject, start, ro, opts);
      p.objects[i].carriedBy = carriedBy;
    } else {
      p.objects[i].name = obj.name;
      p.objects[i].transform = start;
    }
  };
  for (size_t i = 0; i < n; ++i)
    if (atlas.scene.objects[i].kind == ObjectKind::Bone) place(i, p.global);
  std::vector<Eigen::Matrix4d> start(n, p.global);
  if (opts.registration && opts.perObject) start = startPlacements(atlas, p);
  for (size_t i = 0; i < n; ++i)
    if (atlas.scene.objects[i].kind != ObjectKind::Bone) place(i, start[i]);
  keepPairsApart(atlas, p, start);
  p.seconds = since(t0);
  if (progress) progress(1.0, "done");
  return p;
}

Scene placedScene(const Atlas& atlas, const Placement& placement) {
  Scene scene = atlas.scene;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& o = scene.objects[i];
    const Eigen::Matrix4d& t = placement.objects[i].transform;
    transformMesh(o.templ, t);
    // Profiles are learned where the placed template came from: the reference's world (through the object's own
    // source map there, if it has one).
    const Eigen::Matrix4d back = t.inverse();
    o.profileSource = o.profileSource ? Eigen::Matrix4d(*o.profileSource * back) : back;
  }
  return scene;
}

void judgePlacement(const Placement& placement, SegmentationResult& result) {
  for (size_t i = 0; i < placement.objects.size() && i < result.objects.size(); ++i) {
    const ObjectPlacement& o = placement.objects[i];
    if (!o.refusedTooFar) continue;
    ObjectQuality& q = result.objects[i].quality;
    q.status = worseStatus(q.status, QualityStatus::Doubtful);
    const std::string from = o.carriedBy.empty() ? "the global placement" : "where " + o.carriedBy + " placed it";
    q.reasons.push_back("doubtful: its own registration would have moved it " + std::to_string(o.moveDegrees) +
                        " degrees and " + std::to_string(o.moveMm) + " mm from " + from + ", beyond the " +
                        std::to_string(kMaxOwnTurnDegrees) + " degrees / " + std::to_string(kMaxOwnMoveMm) +
                        " mm allowed: its neighbourhood matches best elsewhere");
    result.status = worseStatus(result.status, q.status);
  }
}

size_t atlasSubjectCount(const Atlas& atlas) {
  if (atlas.scene.objects.empty()) return 1;
  return std::max<size_t>(1, atlas.scene.objects.front().profileSubjects.size());
}

Eigen::Matrix4d atlasReferenceToSubject(const Atlas& atlas, size_t k) {
  if (k == 0) return Eigen::Matrix4d::Identity();
  const std::string metaPath = (fs::path(atlas.dir) / "atlas.json").string();
  const Json* sources = jsonMember(atlas.meta, "sources");
  const Json* m = nullptr;
  if (sources && sources->is_array() && k < sources->size())
    if (const Json* reg = jsonMember((*sources)[k], "registration"))
      m = jsonMember(*reg, "transform_reference_to_subject");
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  bool ok = m && m->is_array() && m->size() == 4;
  for (size_t r = 0; ok && r < 4; ++r) {
    const Json& row = (*m)[r];
    ok = row.is_array() && row.size() == 4;
    for (size_t c = 0; ok && c < 4; ++c) {
      ok = row[c].is_number() && std::isfinite(row[c].get<double>());
      if (ok) t(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = row[c].get<double>();
    }
  }
  if (!ok || std::abs(t.topLeftCorner<3, 3>().determinant()) < 1e-9 || t.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
    throw IoError(metaPath, "sources[" + std::to_string(k) +
                                "] has no usable \"registration\": \"transform_reference_to_subject\" (an affine 4x4)");
  return t;
}

Atlas atlasFromSubject(const Atlas& atlas, size_t k) {
  const size_t n = atlasSubjectCount(atlas);
  if (k >= n) throw Error("atlas subject " + std::to_string(k + 1) + " of " + std::to_string(n) + " asked for");
  if (k == 0) return atlas;
  Atlas view = atlas;
  for (SceneObject& o : view.scene.objects) {
    if (o.profileSubjects.size() != n)
      throw IoError(
          (fs::path(atlas.dir) / kScene).string(),
          o.name + " lists " + std::to_string(o.profileSubjects.size()) + " subjects, the atlas " + std::to_string(n));
    const SceneObject::Subject& s = o.profileSubjects[k];
    o.templ = s.surface;
    o.templatePath = s.surfacePath;
    o.profileImage = s.image;
    o.profileImagePath = s.imagePath;
  }
  view.reference = view.scene.objects.front().profileSubjects[k].image;
  return view;
}

namespace {

/// A bone template counts as long when its largest principal spread is at least this many times its second (its
/// length at least twice its width).
constexpr double kLongBoneVarianceRatio = 4.0;

/// The one bone collision partner of object i in `scene` (scene.objects.size() if it has none or several).
size_t oneBonePartner(const Scene& scene, size_t i) {
  const size_t n = scene.objects.size();
  size_t bone = n;
  int bones = 0;
  for (const CollisionPair& pair : scene.collisions) {
    const size_t other = pair.a == static_cast<int>(i)   ? static_cast<size_t>(pair.b)
                         : pair.b == static_cast<int>(i) ? static_cast<size_t>(pair.a)
                                                         : n;
    if (other < n && scene.objects[other].kind == ObjectKind::Bone) {
      bone = other;
      ++bones;
    }
  }
  return bones == 1 ? bone : n;
}

/// The long axis of a bone template (unit direction) through its centroid; false if it is not long.
bool longAxis(const TriangleMesh& bone, Eigen::Vector3d& centre, Eigen::Vector3d& axis) {
  if (bone.vertexCount() < 4) return false;
  centre = bone.vertices.colwise().mean().transpose();
  const Eigen::MatrixXd d = bone.vertices.rowwise() - centre.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(d.transpose() * d);
  const Eigen::Vector3d lambda = es.eigenvalues();  // ascending
  if (!(lambda[2] >= kLongBoneVarianceRatio * lambda[1])) return false;
  axis = es.eigenvectors().col(2).normalized();
  Eigen::Index largest = 0;
  axis.cwiseAbs().maxCoeff(&largest);
  if (axis[largest] < 0) axis = -axis;  // one sign for every run: its largest component positive
  return true;
}

/// A muscle whose one bone collision partner is long, with that bone's long axis (turnedAboutBone()).
struct MuscleOnBone {
  size_t muscle = 0, bone = 0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::UnitZ();
};

/// The muscles of `scene` that lie on one long bone, in object order.
std::vector<MuscleOnBone> musclesOnLongBones(const Scene& scene) {
  std::vector<MuscleOnBone> out;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    if (scene.objects[i].kind != ObjectKind::Muscle) continue;
    MuscleOnBone m;
    m.muscle = i;
    m.bone = oneBonePartner(scene, i);
    if (m.bone < scene.objects.size() && longAxis(scene.objects[m.bone].templ, m.centre, m.axis)) out.push_back(m);
  }
  return out;
}

/// Each object's start among several subjects' (AtlasStarts::Each, an atlas of several): the start whose run reached
/// the highest profile match for it (the first start where no run has one, e.g. the gradient force, and on ties).
std::vector<size_t> bestStarts(const std::vector<AtlasStartRun>& runs) {
  std::vector<size_t> chosen(runs.front().profileMatch.size(), 0);
  for (size_t i = 0; i < chosen.size(); ++i) {
    double best = -std::numeric_limits<double>::infinity();
    for (size_t r = 0; r < runs.size(); ++r) {
      const double m = runs[r].profileMatch[i];
      if (std::isfinite(m) && m > best) {
        best = m;
        chosen[i] = r;
      }
    }
  }
  return chosen;
}

/// `placed` with every object at the global placement, as placeAtlas() leaves it without the objects' own
/// registrations (an affine map keeps disjoint templates disjoint: no pair to pull apart).
Placement globalOnly(const Placement& placed) {
  Placement p = placed;
  for (ObjectPlacement& o : p.objects) {
    ObjectPlacement g;
    g.name = o.name;
    g.transform = placed.global;
    // Its neighbourhood's metric at the global placement, where its own registration started from there.
    g.metricBefore = g.metricAfter = o.carriedBy.empty() ? o.metricBefore : std::numeric_limits<double>::quiet_NaN();
    g.note = "started from the global placement (a start of its own)";
    o = g;
  }
  for (PairPlacement& pp : p.pairs) pp.overlapPlaced = pp.overlapGlobal;
  p.seconds = 0;
  return p;
}

/// Whether every object of `a` has the transform it has in `b`.
bool sameTransforms(const Placement& a, const Placement& b) {
  if (a.objects.size() != b.objects.size()) return false;
  for (size_t i = 0; i < a.objects.size(); ++i)
    if (a.objects[i].transform != b.objects[i].transform) return false;
  return true;
}

/// Remeshes, once, every template of `scene` that a run would remesh (remeshesTemplate()), through the run's template
/// cache where it has one (its hits and misses added to `cacheHits`, `cacheMisses`); a run then uses each as it is.
/// Returns which objects were remeshed.
std::vector<char> remeshTemplatesOnce(Scene& scene, const SegmentOptions& opts, int& cacheHits, int& cacheMisses) {
  std::unique_ptr<MeshCache> cache;
  if (!opts.surface.templateCache.empty()) cache = std::make_unique<MeshCache>(opts.surface.templateCache);
  std::vector<char> remeshed(scene.objects.size(), 0);
  for (size_t i = 0; i < scene.objects.size(); ++i) remeshed[i] = remeshesTemplate(scene.objects[i], opts) ? 1 : 0;
  detail::parallelEach(scene.objects.size(), detail::threadCount(opts.evolution.threads), [&](size_t i) {
    if (!remeshed[i]) return;
    SceneObject& o = scene.objects[i];
    TriangleMesh m = remeshedTemplate(o, cache.get());
    // The subjects' surfaces of an atlas of several share the template's vertices: each is carried onto the new
    // triangulation (every new vertex at its point of the old template, with the same small offset from it).
    if (!o.profileSubjects.empty()) {
      const SurfaceTransfer transfer(o.templ, m.vertices);
      const Points offset = m.vertices - transfer.apply(o.templ.vertices);
      for (SceneObject::Subject& sub : o.profileSubjects) {
        TriangleMesh carried = m;
        carried.vertices = transfer.apply(sub.surface.vertices) + offset;
        sub.surface = std::move(carried);
      }
    }
    o.templ = std::move(m);
    o.model.remesh = false;
  });
  if (cache) {
    cacheHits += cache->hits();
    cacheMisses += cache->misses();
  }
  return remeshed;
}

/// The sum of a run's finite profile matches (0 if none has one).
double matchSum(const AtlasStartRun& run) {
  double sum = 0;
  for (double m : run.profileMatch) sum += std::isfinite(m) ? m : 0.0;
  return sum;
}

}  // namespace

int turnedAboutBone(const Atlas& atlas, Placement& placement, double degrees) {
  int turned = 0;
  for (const MuscleOnBone& m : musclesOnLongBones(atlas.scene)) {
    if (m.muscle >= placement.objects.size()) continue;
    ++turned;
    if (degrees == 0) continue;
    const Eigen::Matrix3d r = Eigen::AngleAxisd(degrees * EIGEN_PI / 180.0, m.axis).toRotationMatrix();
    Eigen::Matrix4d turn = Eigen::Matrix4d::Identity();
    turn.topLeftCorner<3, 3>() = r;
    turn.topRightCorner<3, 1>() = m.centre - r * m.centre;
    placement.objects[m.muscle].transform = placement.objects[m.muscle].transform * turn;
  }
  return turned;
}

std::vector<double> atlasStartTwists(const Atlas& atlas, AtlasStarts starts) {
  if (starts != AtlasStarts::Each || atlasSubjectCount(atlas) != 1 || musclesOnLongBones(atlas.scene).empty())
    return {0.0};
  std::vector<double> twists{0.0};
  for (int k = 1; k <= kStartTwistSteps; ++k) {
    twists.push_back(-k * kStartTwistDegrees);
    twists.push_back(k * kStartTwistDegrees);
  }
  return twists;
}

AtlasSegmentation segmentWithAtlas(const Atlas& atlas, const ImageF& image, const PlacementOptions& placing,
                                   const SegmentOptions& opts, AtlasStarts starts, const ProgressFn& progress,
                                   const std::function<void(Scene&)>& beforeRun) {
  const size_t subjects = starts == AtlasStarts::Each ? atlasSubjectCount(atlas) : 1;
  const std::vector<double> twists = atlasStartTwists(atlas, starts);
  // An atlas of one subject also starts every object from the global placement, as if no object had been registered
  // on its own: an object's neighbourhood may match best where the learned appearance does not (on the real CT and MR
  // of docs/measurements.md, the muscles), and the run's profile match tells which placement was the better start.
  const bool globalStart = starts == AtlasStarts::Each && subjects == 1 && placing.registration && placing.perObject;
  const size_t startCount = subjects * twists.size() + (globalStart ? 1 : 0);
  const bool several = startCount > 1;
  // One subject's turned starts differ only in how far all its muscles on a bone are turned: the start whose run
  // matched the learned appearance best is kept whole. Several subjects' starts are each object's own choice, and a
  // final run evolves every object from its start side by side.
  const bool turnedOnly = several && subjects == 1;
  // Several starts are compared on their coarse levels alone (EvolutionOptions::coarseOnly): a start decides which
  // boundary the coarse level takes each surface to, and the finest level moves it by about a voxel (docs/
  // measurements.md, "Starts compared on their coarse level": the same mean Dice on 24 posed phantom subjects in two
  // thirds of the time). The kept starts then run whole in a final run. With one level there is nothing to compare on:
  // every start runs whole, and one subject's best run is the result.
  const bool screening = several && resolveSettings(opts, image.grid).levels > 1;
  const bool finalRun = several && (!turnedOnly || screening);
  const size_t runs = finalRun ? startCount + 1 : startCount;
  // A final run's choice needs only each start's evolved surfaces (their profile match is taken before the output
  // separation): its starts skip the separation, and the final run, whose surfaces are the ones written, does it.
  // The runs derive their meshes without the template cache: what they derive (the placed templates' coarser levels)
  // depends on this case's placement and would only fill the cache with entries no other case reads; the atlas's
  // templates were remeshed through it, once.
  SegmentOptions runOpts = opts;
  runOpts.surface.templateCache.clear();
  SegmentOptions startOpts = runOpts;
  if (finalRun) startOpts.collision.separationSweeps = 0;
  startOpts.evolution.coarseOnly = screening;
  auto share = [&](size_t run, const std::string& what) -> ProgressFn {
    if (!progress) return {};
    return [&progress, run, runs, what](double f, const std::string& stage) {
      progress((static_cast<double>(run) + f) / static_cast<double>(runs), what + stage);
    };
  };
  const size_t n = atlas.scene.objects.size();
  std::vector<Scene> scenes;
  AtlasSegmentation out;
  std::vector<std::vector<char>> remeshed(subjects);  // per subject, the templates remeshed here
  int cacheHits = 0, cacheMisses = 0;                 // of that remeshing
  FeatureStore features;  // the image's and the profile images' features, computed by the first run that needs them
  size_t kept = 0;        // without a final run, the start whose run is the result; with one, the reference's (start 0)
  for (size_t k = 0; k < subjects; ++k) {
    const auto t0 = Clock::now();
    // The templates a run would remesh, remeshed here once in the atlas's space: every start places the same
    // triangulation instead of remeshing its own, and a template cache serves every case of a cohort.
    Atlas view = atlasFromSubject(atlas, k);
    remeshed[k] = remeshTemplatesOnce(view.scene, opts, cacheHits, cacheMisses);
    PlacementOptions po = placing;
    if (k > 0 && (placing.start || !placing.registration))
      po.start = Eigen::Matrix4d(placing.start.value_or(Eigen::Matrix4d::Identity()) *
                                 atlasReferenceToSubject(atlas, k).inverse());
    // One placement per subject; its turned starts differ only in their muscles' transforms, the global start (after
    // the turned ones) in every object's.
    Placement placed;
    const size_t subjectStarts = twists.size() + (globalStart ? 1 : 0);
    for (size_t t = 0; t < subjectStarts; ++t) {
      const bool global = t == twists.size();
      const size_t index = k * twists.size() + t;
      std::string what;
      if (subjects > 1) what += "subject " + std::to_string(k + 1);
      if (global)
        what += (what.empty() ? "" : ", ") + std::string("global placement");
      else if (twists.size() > 1)
        what += (what.empty() ? "" : ", ") + ("turned " + std::to_string(std::lround(twists[t])) + "°");
      const ProgressFn part = share(index, what.empty() ? "" : what + ": ");
      ProgressFn placingPart, segmentPart;
      const double placingShare = t == 0 ? 0.1 : 0.0;
      if (part) {
        placingPart = [&part, placingShare](double f, const std::string& s) { part(placingShare * f, s); };
        segmentPart = [&part, placingShare](double f, const std::string& s) {
          part(placingShare + (1 - placingShare) * f, s);
        };
      }
      const auto ts = Clock::now();
      if (t == 0) placed = placeAtlas(view, image, po, placingPart);
      Placement p = global ? globalOnly(placed) : placed;
      if (global && sameTransforms(p, placed)) continue;  // no object kept a placement of its own: the first start
      if (!global && twists[t] != 0) turnedAboutBone(view, p, twists[t]);
      Scene scene = placedScene(view, p);
      if (beforeRun) beforeRun(scene);
      SegmentationResult r = segmentScene(image, scene, startOpts, segmentPart, &features);
      judgePlacement(p, r);
      AtlasStartRun run;
      run.subject = k;
      run.twistDegrees = global ? 0.0 : twists[t];
      run.globalPlacement = global;
      run.coarseLevelsOnly = screening;
      for (const ObjectResult& o : r.objects) {
        run.profileMatch.push_back(o.quality.profileMatch);
        run.status.push_back(o.quality.status);
      }
      run.placement = std::move(p);
      if (t > 0) run.placement.seconds = 0;  // placed once, with the subject's first start
      run.secondsPerStage = r.secondsPerStage;
      run.seconds = t == 0 ? since(t0) : since(ts);
      const bool best = !turnedOnly || out.starts.empty() || matchSum(run) > matchSum(out.starts[kept]);
      if (turnedOnly && best) kept = out.starts.size();
      out.starts.push_back(std::move(run));
      scenes.push_back(std::move(scene));
      if (!finalRun && best) out.result = std::move(r);
    }
  }
  out.chosen = turnedOnly ? std::vector<size_t>(n, kept) : bestStarts(out.starts);
  // The result's objects whose templates were remeshed here, before the placement, count as remeshed, and that
  // remeshing's template cache entries as the run's.
  const auto markRemeshed = [&] {
    out.result.templateCacheHits += cacheHits;
    out.result.templateCacheMisses += cacheMisses;
    for (size_t i = 0; i < n && i < out.result.objects.size(); ++i)
      out.result.objects[i].remeshed =
          out.result.objects[i].remeshed || remeshed[out.starts[out.chosen[i]].subject][i] != 0;
  };
  out.placement = out.starts[kept].placement;
  out.placement.seconds = 0;
  for (const AtlasStartRun& r : out.starts) out.placement.seconds += r.placement.seconds;
  if (!finalRun) {
    markRemeshed();
    out.scene = std::move(scenes[kept]);
    if (progress) progress(1.0, "done");
    return out;
  }
  // The final placement: the reference's global placement, each object its start's own (in that subject's world).
  for (size_t i = 0; i < n; ++i) out.placement.objects[i] = out.starts[out.chosen[i]].placement.objects[i];
  // Each object from its best start, side by side, in one run with every collision pair; the pairs measured again.
  out.scene = scenes[0];
  for (size_t i = 0; i < n; ++i) out.scene.objects[i] = scenes[out.chosen[i]].objects[i];
  for (size_t c = 0; c < out.scene.collisions.size() && c < out.placement.pairs.size(); ++c) {
    const CollisionPair& cp = out.scene.collisions[c];
    out.placement.pairs[c].overlapPlaced = pairOverlap(out.scene.objects[static_cast<size_t>(cp.a)].templ,
                                                       out.scene.objects[static_cast<size_t>(cp.b)].templ);
  }
  out.result = segmentScene(image, out.scene, runOpts, share(startCount, "from the best starts: "), &features);
  judgePlacement(out.placement, out.result);
  markRemeshed();
  if (progress) progress(1.0, "done");
  return out;
}

Json placementJson(const Placement& placement) {
  Json j;
  j["metric"] = placement.metric.empty() ? Json() : Json(placement.metric);
  j["global_atlas_to_subject_ras"] = matrixJson(placement.global);
  j["seconds"] = placement.seconds;
  if (placement.registration) {
    const RegistrationResult& r = *placement.registration;
    Json reg;
    reg["metric_start"] = r.startMetric;
    reg["metric_end"] = r.metric;
    reg["overlap"] = r.overlap;
    reg["seconds"] = r.seconds;
    Json stages = Json::array();
    for (const RegistrationStage& s : r.stages) {
      Json st;
      st["stage"] = s.name;
      st["metric_before"] = s.metricBefore;
      st["metric_after"] = s.metricAfter;
      st["iterations"] = s.iterations;
      st["seconds"] = s.seconds;
      stages.push_back(st);
    }
    reg["stages"] = stages;
    j["global_registration"] = reg;
  }
  Json objects = Json::array();
  for (const ObjectPlacement& o : placement.objects) {
    Json oj;
    oj["name"] = o.name;
    oj["own_registration_kept"] = o.registered;
    if (!o.note.empty()) oj["note"] = o.note;
    oj["atlas_to_subject_ras"] = matrixJson(o.transform);
    oj["metric_before"] = std::isfinite(o.metricBefore) ? Json(o.metricBefore) : Json();
    oj["metric_after"] = std::isfinite(o.metricAfter) ? Json(o.metricAfter) : Json();
    oj["started_from"] = o.carriedBy.empty() ? std::string("global placement") : o.carriedBy;
    oj["own_move_degrees"] = o.moveDegrees;
    oj["own_move_mm"] = o.moveMm;
    oj["scale"] = std::cbrt(std::abs(o.transform.topLeftCorner<3, 3>().determinant()));
    oj["seconds"] = o.seconds;
    objects.push_back(oj);
  }
  j["objects"] = objects;
  Json pairs = Json::array();
  for (const PairPlacement& pp : placement.pairs) {
    Json pj;
    pj["pair"] = Json::array({pp.a, pp.b});
    pj["vertices_inside_partner_global"] = pp.overlapGlobal;
    pj["vertices_inside_partner_placed"] = pp.overlapPlaced;
    pairs.push_back(pj);
  }
  j["pairs"] = pairs;
  return j;
}

Json atlasStartsJson(const AtlasSegmentation& seg, const Scene& scene) {
  Json j;
  size_t subjects = 0;
  for (const AtlasStartRun& r : seg.starts) subjects = std::max(subjects, r.subject + 1);
  j["subjects"] = subjects;
  j["starts"] = seg.starts.size();
  Json runs = Json::array();
  for (const AtlasStartRun& r : seg.starts) {
    Json rj;
    rj["subject"] = r.subject + 1;
    rj["twist_degrees"] = r.twistDegrees;
    rj["objects_placed"] = r.globalPlacement ? "global placement" : "own registrations";
    rj["levels_evolved"] = r.coarseLevelsOnly ? "coarse" : "all";
    if (r.placement.registration) rj["global_metric"] = r.placement.registration->metric;
    rj["seconds"] = r.seconds;
    rj["placement_seconds"] = r.placement.seconds;
    Json timing = Json::object();
    for (const auto& [stage, sec] : r.secondsPerStage) timing[stage + "_s"] = sec;
    rj["timing"] = timing;
    Json objects = Json::object();
    for (size_t i = 0; i < r.profileMatch.size() && i < scene.objects.size(); ++i)
      objects[scene.objects[i].name] = {
          {"profile_match", std::isfinite(r.profileMatch[i]) ? Json(r.profileMatch[i]) : Json()},
          {"status", qualityStatusName(r.status[i])}};
    rj["objects"] = objects;
    runs.push_back(rj);
  }
  j["runs"] = runs;
  Json chosen = Json::object();
  for (size_t i = 0; i < seg.chosen.size() && i < scene.objects.size(); ++i)
    chosen[scene.objects[i].name] = seg.chosen[i] + 1;
  j["start_of_each_object"] = chosen;
  return j;
}

}  // namespace msk
