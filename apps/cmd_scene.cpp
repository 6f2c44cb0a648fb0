// mskseg scene: a ready-to-run scene (scene.json and one template per object) from the labels of a label map, for
// example the contralateral structures of the same scan, mirrored across the midline.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <set>
#include <sstream>

#include "args.h"
#include "commands.h"
#include "msk/core/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
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
  Args args(argv, {"labels", "objects", "out", "mirror-x", "midline-label", "vertices", "smooth", "collisions"},
            {"help", "refine-bones"});
  if (args.has("help")) {
    std::cout
        << "usage: mskseg scene --labels SEG.nii.gz --objects SPEC --out DIR [--mirror-x MM | --midline-label L]\n"
           "                    [--vertices 3000] [--smooth MM] [--collisions auto|all|none] [--refine-bones]\n\n"
           "Writes a scene ready for `mskseg segment`/`batch`: DIR/templates/<name>.vtk (LPS), one smooth template\n"
           "per object built from a label of SEG as `mskseg template` builds it, and DIR/scene.json naming them.\n"
           "  --objects SPEC   comma-separated NAME:LABEL[:FROM][:KIND]: LABEL is the object's label in the results\n"
           "                   (and in a reference to score against), FROM the label its template is built from\n"
           "                   (default LABEL), KIND bone, muscle or generic (default generic), e.g.\n"
           "                   femur_right:76:75:bone,gluteus_medius_right:83:82:muscle\n"
           "  --mirror-x MM    mirror every template across the sagittal plane x = MM (RAS mm): templates of one\n"
           "                   side from the other side's labels. Each object then uses the profile force with its\n"
           "                   intensity profiles learned on the structure it came from (\"profiles_from\")\n"
           "  --midline-label L   the same, across x = the centroid of label L (e.g. the sacrum)\n"
           "  --collisions     auto: pairs whose templates come within 2 mm (default); all: every pair; none\n"
           "  --refine-bones   bones take the refinement pass (\"refine\": true; for CT, see README)\n"
           "  --vertices, --smooth   as for `mskseg template`\n"
           "The folder appears whole or not at all.\n";
    return 0;
  }
  if (!args.positional().empty()) throw UsageError("unexpected argument '" + args.positional()[0] + "'");
  const std::string labelsPath = args.str("labels"), out = args.str("out");
  const std::vector<ObjectSpec> objects = parseObjects(args.str("objects"));
  if (args.has("mirror-x") && args.has("midline-label"))
    throw UsageError("give --mirror-x or --midline-label, not both");
  const TemplateOptions topts = templateOptionsFrom(args);
  const std::string collisions = args.str("collisions", "auto");
  if (collisions != "auto" && collisions != "all" && collisions != "none")
    throw ParameterError("--collisions", collisions, "must be auto, all or none");
  checkOutputFolder(out);

  const LabelMap labels = readNifti<int32_t>(labelsPath);
  for (const ObjectSpec& o : objects) requireLabel(labels, o.from, labelsPath);
  const bool mirror = args.has("mirror-x") || args.has("midline-label");
  double midX = args.num("mirror-x", 0.0);
  if (args.has("midline-label")) {
    const long m = args.integer("midline-label", 0);
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
    Json scene;
    Json list = Json::array();
    for (const ObjectSpec& o : objects) {
      TemplateReport report;
      TriangleMesh mesh = templateFromLabels(labels, static_cast<int>(o.from), topts, &report);
      if (mirror) mesh = mirrorMesh(mesh, Eigen::Vector3d(midX, 0, 0), Eigen::Vector3d::UnitX());
      writeMesh(dir + "/templates/" + o.name + ".vtk", mesh, MeshSpace::LPS);
      Json j;
      j["name"] = o.name;
      j["label"] = static_cast<double>(o.label);
      j["kind"] = o.kind;
      j["template"] = "templates/" + o.name + ".vtk";
      if (mirror) {
        j["force"] = "profile";
        Json from;
        from["mirror_x"] = midX;
        j["profiles_from"] = from;
      }
      if (args.has("refine-bones") && o.kind == "bone") {
        Json model;
        model["refine"] = true;
        j["model"] = model;
      }
      list.push(j);
      std::cout << o.name << " (label " << o.label << "): template from label " << o.from << ", " << mesh.vertexCount()
                << " vertices, " << enclosedVolume(mesh) / 1000.0 << " mL" << (mirror ? ", mirrored" : "") << "\n";
    }
    scene["objects"] = list;
    if (collisions == "auto") {
      scene["collisions"] = "auto";
    } else if (collisions == "all") {
      Json pairs = Json::array();
      for (size_t a = 0; a < objects.size(); ++a)
        for (size_t b = a + 1; b < objects.size(); ++b) pairs.push(Json(Json::Array{objects[a].name, objects[b].name}));
      scene["collisions"] = pairs;
    }
    scene.writeFile(dir + "/scene.json");
  });
  if (mirror) std::cout << "templates mirrored across x = " << fixed2(midX) << " mm (RAS)\n";
  std::cout << "scene: " << out << "/scene.json (" << objects.size() << " objects, collisions " << collisions << ")\n";
  return 0;
}

}  // namespace msk::cli
