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
  std::string name, kind = "generic";
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
      const bool isKind = parts[p] == "bone" || parts[p] == "muscle" || parts[p] == "generic";
      if (isKind && p + 1 == parts.size()) {
        o.kind = parts[p];
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

}  // namespace

int cmdScene(const std::vector<std::string>& argv) {
  CommandLine app(
      "scene",
      "Writes a scene ready for `mskseg segment`/`batch`: OUT/templates/<name>.vtk (LPS), one smooth template per "
      "object built from a label of SEG as `mskseg template` builds it, and OUT/scene.json naming them. The folder "
      "appears whole or not at all.");
  std::string labelsPath, out, objectsText, collisions = "auto";
  std::optional<double> mirrorX;
  std::optional<long> midlineLabel;
  bool refineBones = false;
  TemplateOptions topts;
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
  app.add_option("--collisions", collisions,
                 "auto: pairs whose templates come within 2 mm (default); all: every pair; none");
  app.add_flag("--refine-bones", refineBones, "bones take the refinement pass (\"refine\": true; for CT)");
  addTemplateOptions(app, topts);
  if (!parseArgs(app, argv)) return 0;
  const std::vector<ObjectSpec> objects = parseObjects(objectsText);
  checkTemplateOptions(topts);
  if (collisions != "auto" && collisions != "all" && collisions != "none")
    throw ParameterError("--collisions", collisions, "must be auto, all or none");
  if (mirrorX && !std::isfinite(*mirrorX)) throw ParameterError("--mirror-x", std::to_string(*mirrorX), "must be finite");
  checkOutputFolder(out);

  const LabelMap labels = readNifti<int32_t>(labelsPath);
  for (const ObjectSpec& o : objects) requireLabel(labels, o.from, labelsPath);
  const bool mirror = mirrorX || midlineLabel;
  double midX = mirrorX.value_or(0.0);
  if (midlineLabel) {
    const long m = *midlineLabel;
    requireLabel(labels, m, labelsPath);
    double sum = 0;
    long n = 0;
    const Grid& g = labels.grid;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i)
          if (labels.at(i, j, k) == m) {
            sum += g.toWorld(Eigen::Vector3d(i, j, k)).x();
            ++n;
          }
    midX = sum / static_cast<double>(n);
  }

  writeFolderAtomically(out, [&](const std::string& dir) {
    std::filesystem::create_directories(dir + "/templates");
    Scene scene;
    for (const ObjectSpec& o : objects) {
      TemplateReport report;
      TriangleMesh mesh = templateFromLabels(labels, static_cast<int>(o.from), topts, &report);
      if (mirror) mesh = mirrorMesh(mesh, Eigen::Vector3d(midX, 0, 0), Eigen::Vector3d::UnitX());
      SceneObject so;
      so.name = o.name;
      so.label = static_cast<int>(o.label);
      so.kind = o.kind == "bone" ? ObjectKind::Bone : o.kind == "muscle" ? ObjectKind::Muscle : ObjectKind::Generic;
      so.model = defaultModel(so.kind);
      so.templatePath = dir + "/templates/" + o.name + ".vtk";
      writeMesh(so.templatePath, mesh, MeshSpace::LPS);
      if (mirror) {
        so.hasForce = true;
        so.force = so.model.imageForce = TargetMode::Profile;
        Eigen::Matrix4d source = Eigen::Matrix4d::Identity();
        source(0, 0) = -1;
        source(0, 3) = 2 * midX;
        so.profileSource = source;
      }
      if (refineBones && so.kind == ObjectKind::Bone) so.model.refine = true;
      scene.objects.push_back(std::move(so));
      std::cout << o.name << " (label " << o.label << "): template from label " << o.from << ", " << mesh.vertexCount()
                << " vertices, " << enclosedVolume(mesh) / 1000.0 << " mL" << (mirror ? ", mirrored" : "") << "\n";
    }
    if (collisions == "auto") scene.autoCollisions = AutoCollisions{};
    if (collisions == "all")
      for (size_t a = 0; a < objects.size(); ++a)
        for (size_t b = a + 1; b < objects.size(); ++b)
          scene.collisions.push_back(CollisionPair{static_cast<int>(a), static_cast<int>(b)});
    Json provenance = Json::object();
    provenance["generator"] = "mskseg scene";
    provenance["command"] = commandLineJson("scene", argv);
    provenance["labels"] = std::filesystem::absolute(labelsPath).string();
    scene.provenance = provenance;
    writeScene(scene, dir + "/scene.json");
  });
  if (mirror) std::cout << "templates mirrored across x = " << fixed2(midX) << " mm (RAS)\n";
  std::cout << "scene: " << out << "/scene.json (" << objects.size() << " objects, collisions " << collisions << ")\n";
  return 0;
}

}  // namespace msk::cli
