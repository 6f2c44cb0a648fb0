// mskseg scene: a ready-to-run scene (scene.json and one template per object) from the labels of a label map, for
// example the contralateral structures of the same scan, mirrored across the midline.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>

#include "commands.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/template_builder.h"

namespace msk::cli {
namespace {

/// One object of --objects: NAME:LABEL[:FROM][:KIND].
struct ObjectSpec {
  std::string name;
  ObjectKind kind = ObjectKind::Generic;
  long label = 0, from = 0;
};

long labelNumber(const std::string& text, const std::string& item) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < 1 || v > 2147483647L)
    throw ParameterError("--objects", item, "'" + text + "' is not a label (a whole number 1..2147483647)");
  return v;
}

std::vector<ObjectSpec> parseObjects(const std::string& text) {
  std::vector<ObjectSpec> out;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    std::vector<std::string> parts;
    std::stringstream fields(item);
    std::string f;
    while (std::getline(fields, f, ':')) parts.push_back(f);
    if (parts.size() < 2 || parts.size() > 4 || parts[0].empty())
      throw ParameterError("--objects", item, "each object is NAME:LABEL[:FROM][:KIND]");
    ObjectSpec o;
    o.name = parts[0];
    o.label = labelNumber(parts[1], item);
    o.from = o.label;
    for (size_t p = 2; p < parts.size(); ++p) {
      const std::optional<ObjectKind> kind = parseObjectKind(parts[p]);
      if (kind && p + 1 == parts.size()) {
        o.kind = *kind;
      } else if (p == 2) {
        o.from = labelNumber(parts[p], item);
      } else {
        throw ParameterError("--objects", item, "KIND must be bone, muscle or generic");
      }
    }
    for (const ObjectSpec& other : out) {
      if (other.name == o.name) throw ParameterError("--objects", item, "the name " + o.name + " is given twice");
      if (other.label == o.label)
        throw ParameterError(
            "--objects", item,
            "label " + std::to_string(o.label) + " is also " + other.name + "'s (results need one each)");
    }
    out.push_back(o);
  }
  if (out.empty()) throw ParameterError("--objects", text, "names no object");
  return out;
}

std::string fixed2(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

/// What `mskseg scene` builds: the objects, their templates' options, the mirror plane and the collision pairs.
struct SceneRequest {
  std::vector<ObjectSpec> objects;
  TemplateOptions templates;
  bool mirror = false;
  double mirrorX = 0;  ///< mm (RAS)
  bool refineBones = false;
  std::string collisions = "auto";
};

/// x (RAS mm) of the centroid of the voxels of `label`, which must be present.
double labelCentroidX(const LabelMap& labels, long label) {
  double sum = 0;
  long n = 0;
  const Grid& g = labels.grid;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        if (labels.at(i, j, k) == label) {
          sum += g.toWorld(Eigen::Vector3d(i, j, k)).x();
          ++n;
        }
  return sum / static_cast<double>(n);
}

/// Object `o` of the scene with its template written to `templatePath` (mirrored, with its profiles learned where it
/// came from, if the request mirrors).
SceneObject sceneObject(const ObjectSpec& o, const LabelMap& labels, const SceneRequest& r,
                        const std::string& templatePath) {
  TemplateReport report;
  TriangleMesh mesh = templateFromLabels(labels, static_cast<int>(o.from), r.templates, &report);
  if (r.mirror) mesh = mirrorMesh(mesh, Eigen::Vector3d(r.mirrorX, 0, 0), Eigen::Vector3d::UnitX());
  SceneObject so;
  so.name = o.name;
  so.label = static_cast<int>(o.label);
  so.kind = o.kind;
  so.model = defaultModel(so.kind);
  so.templatePath = templatePath;
  writeMesh(so.templatePath, mesh, MeshSpace::LPS);
  if (r.mirror) {
    so.hasForce = true;
    so.force = so.model.imageForce = TargetMode::Profile;
    Eigen::Matrix4d source = Eigen::Matrix4d::Identity();
    source(0, 0) = -1;
    source(0, 3) = 2 * r.mirrorX;
    so.profileSource = source;
  }
  if (r.refineBones && so.kind == ObjectKind::Bone) so.model.refine = true;
  std::cout << o.name << " (label " << o.label << "): template from label " << o.from << ", " << mesh.vertexCount()
            << " vertices, " << enclosedVolume(mesh) / 1000.0 << " mL" << (r.mirror ? ", mirrored" : "") << "\n";
  return so;
}

/// The scene folder in `dir`: templates/<name>.vtk and scene.json (its provenance the command and the labels file).
void writeSceneFolder(const std::string& dir, const LabelMap& labels, const SceneRequest& r,
                      const std::vector<std::string>& argv, const std::string& labelsPath) {
  std::filesystem::create_directories(dir + "/templates");
  Scene scene;
  for (const ObjectSpec& o : r.objects)
    scene.objects.push_back(sceneObject(o, labels, r, dir + "/templates/" + o.name + ".vtk"));
  if (r.collisions == "auto") scene.autoCollisions = AutoCollisions{};
  if (r.collisions == "all")
    for (size_t a = 0; a < r.objects.size(); ++a)
      for (size_t b = a + 1; b < r.objects.size(); ++b)
        scene.collisions.push_back(CollisionPair{static_cast<int>(a), static_cast<int>(b)});
  Json provenance = Json::object();
  provenance["generator"] = "mskseg scene";
  provenance["command"] = commandLineJson("scene", argv);
  provenance["labels"] = std::filesystem::absolute(labelsPath).string();
  scene.provenance = provenance;
  writeScene(scene, dir + "/scene.json");
}

}  // namespace

int cmdScene(const std::vector<std::string>& argv) {
  CommandLine app(
      "scene",
      "Writes a scene ready for `mskseg segment`/`batch`: OUT/templates/<name>.vtk (LPS), one smooth template per "
      "object built from a label of SEG as `mskseg template` builds it, and OUT/scene.json naming them. The folder "
      "appears whole or not at all.");
  std::string labelsPath, out, objectsText;
  std::optional<double> mirrorX;
  std::optional<long> midlineLabel;
  SceneRequest r;
  app.add_option("--labels", labelsPath, "label map (NIfTI)")->required();
  app.add_option("--objects", objectsText,
                 "comma-separated NAME:LABEL[:FROM][:KIND]: LABEL is the object's label in the results (and in a "
                 "reference to score against), FROM the label its template is built from (default LABEL), KIND bone, "
                 "muscle or generic (default generic), e.g. femur_right:76:75:bone,gluteus_medius_right:83:82:muscle")
      ->required();
  app.add_option("--out", out, "output folder")->required();
  auto* mirrorOption = app.add_option_function<double>(
                              "--mirror-x", [&mirrorX](double x) { mirrorX = x; },
                              "mirror every template across the sagittal plane x = MM (RAS mm): templates of one side "
                              "from the other side's labels; each object then uses the profile force with its "
                              "intensity profiles learned on the structure it came from (\"profiles_from\")")
                           ->type_name("MM");
  app.add_option_function<long>(
         "--midline-label", [&midlineLabel](long l) { midlineLabel = l; },
         "the same, across x = the centroid of label L (e.g. the sacrum)")
      ->type_name("L")
      ->excludes(mirrorOption);
  app.add_option("--collisions", r.collisions,
                 "auto: pairs whose templates come within 2 mm (default); all: every pair; none");
  app.add_flag("--refine-bones", r.refineBones, "bones take the refinement pass (\"refine\": true; for CT)");
  addTemplateOptions(app, r.templates);
  if (!parseArgs(app, argv)) return 0;
  r.objects = parseObjects(objectsText);
  checkTemplateOptions(r.templates);
  if (r.collisions != "auto" && r.collisions != "all" && r.collisions != "none")
    throw ParameterError("--collisions", r.collisions, "must be auto, all or none");
  if (mirrorX && !std::isfinite(*mirrorX))
    throw ParameterError("--mirror-x", std::to_string(*mirrorX), "must be finite");
  checkOutputFolder(out);

  const LabelMap labels = readNifti<int32_t>(labelsPath);
  for (const ObjectSpec& o : r.objects) requireLabel(labels, o.from, labelsPath);
  r.mirror = mirrorX || midlineLabel;
  r.mirrorX = mirrorX.value_or(0.0);
  if (midlineLabel) {
    requireLabel(labels, *midlineLabel, labelsPath);
    r.mirrorX = labelCentroidX(labels, *midlineLabel);
  }
  writeFolderAtomically(out, [&](const std::string& dir) { writeSceneFolder(dir, labels, r, argv, labelsPath); });
  if (r.mirror) std::cout << "templates mirrored across x = " << fixed2(r.mirrorX) << " mm (RAS)\n";
  std::cout << "scene: " << out << "/scene.json (" << r.objects.size() << " objects, collisions " << r.collisions
            << ")\n";
  return 0;
}

}  // namespace msk::cli
