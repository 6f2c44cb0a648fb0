#include "msk/segmentation/scene.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/nifti_io.h"
#include "msk/segmentation/segment_options.h"
#include "msk/segmentation/surface_proximity.h"
#include "msk/segmentation/surface_quality.h"

namespace fs = std::filesystem;

namespace msk {

namespace {

const std::vector<std::string> kTopKeys = {"objects", "collisions", "description", "provenance"};
const std::vector<std::string> kObjectKeys = {"name",  "label", "kind",          "template", "polarity",
                                              "force", "model", "profiles_from", "colour"};
const std::vector<std::string> kModelKeys = {"shape_memory", "internal_stiffness", "global_prior",    "image_force",
                                             "medial_axis",  "radial_stiffness",   "axis_spacing_mm", "axis_first",
                                             "volumetric",   "volume_stiffness",   "refine",          "remesh"};
const std::vector<std::string> kPairParameterKeys = {"gap_mm", "proximity_mm", "friction",
                                                     "mode",   "target",       "resolution"};
// The scene's names of the TargetModes, in the enum's order (parsed and written by index).
const std::vector<std::string> kForces = {"gradient", "profile"};
constexpr double kAutoWithinMm = 2.0;  // "collisions": "auto"

std::string joined(const std::vector<std::string>& words) {
  std::string s;
  for (const auto& w : words) s += (s.empty() ? "" : ", ") + w;
  return s;
}

/// A number as a message shows it (0.5, 10, 1e+300).
std::string plain(double x) {
  std::ostringstream out;
  out << x;
  return out.str();
}

/// A value as it appears in the file, shortened for messages.
std::string shown(const Json& v) {
  std::string s = v.dump(-1);
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

/// Reports problems of one scene as IoError(scene file, "<where>: <problem>").
class Checker {
 public:
  explicit Checker(std::string path) : path_(std::move(path)) {}
  [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
    throw IoError(path_, where.empty() ? problem : where + ": " + problem);
  }
  /// Throws on any key of `obj` not in `known`.
  void knownKeys(const Json& obj, const std::vector<std::string>& known, const std::string& where,
                 const char* what) const {
    for (const auto& kv : obj.items())
      if (std::find(known.begin(), known.end(), kv.key()) == known.end())
        fail(where, std::string("unknown ") + what + " \"" + kv.key() + "\" (known: " + joined(known) + ")");
  }
  /// A string member, required or optional (nullptr if absent and optional).
  const std::string* string(const Json& obj, const std::string& key, const std::string& where, bool required) const {
    const Json* v = jsonMember(obj, key);
    if (!v) {
      if (required) fail(where, "missing key \"" + key + "\"");
      return nullptr;
    }
    if (!v->is_string()) fail(where, "\"" + key + "\" must be a string, found " + v->type_name() + " " + shown(*v));
    if (v->get<std::string>().empty()) fail(where, "\"" + key + "\" must not be empty");
    return &v->get_ref<const std::string&>();
  }
  /// An optional string member restricted to `choices`; returns its index or -1 if absent.
  int choice(const Json& obj, const std::string& key, const std::vector<std::string>& choices, const std::string& where,
             bool required) const {
    const std::string* s = string(obj, key, where, required);
    if (!s) return -1;
    auto it = std::find(choices.begin(), choices.end(), *s);
    if (it == choices.end())
      fail(where, "\"" + key + "\" must be one of " + joined(choices) + ", found \"" + *s + "\"");
    return static_cast<int>(it - choices.begin());
  }
  /// An optional boolean member (nullptr if absent).
  const bool* boolean(const Json& obj, const std::string& key, const std::string& where, bool* store) const {
    const Json* v = jsonMember(obj, key);
    if (!v) return nullptr;
    if (!v->is_boolean())
      fail(where, "\"" + key + "\" must be true or false, found " + v->type_name() + " " + shown(*v));
    *store = v->get<bool>();
    return store;
  }
  /// Range of an optional number.
  /// An optional finite number member in [lo, hi] ((lo, hi] if `lowOpen`), the range of its command-line twin;
  /// `*store` set and true if present.
  bool numberIn(const Json& obj, const std::string& key, double lo, double hi, bool lowOpen, const std::string& where,
                double* store) const {
    const Json* v = jsonMember(obj, key);
    if (!v) return false;
    const double x = v->is_number() ? v->get<double>() : std::nan("");
    if (!(std::isfinite(x) && (lowOpen ? x > lo : x >= lo) && x <= hi))
      fail(where, "\"" + key + "\" must be a number in " + (lowOpen ? "(" : "[") + plain(lo) + ", " + plain(hi) +
                      "], found " + shown(*v));
    *store = x;
    return true;
  }

 private:
  std::string path_;
};

std::string objectWhere(size_t i, const std::string& name) {
  std::string w = "objects[" + std::to_string(i) + "]";
  if (!name.empty()) w += " (" + name + ")";
  return w;
}

/// The object's "model" entry applied over defaultModel(kind). "force" (object level) is a synonym of "image_force";
/// either one also sets obj.hasForce / obj.force (read by the segmenter).
ObjectModel parseModel(const Checker& check, const Json& o, const std::string& where, SceneObject& obj) {
  ObjectModel m = defaultModel(obj.kind);
  const std::string at = where + " model";
  const Json empty = Json::object();
  const Json* model = jsonMember(o, "model");
  if (!model) model = &empty;
  if (!model->is_object())
    check.fail(at, std::string("expected an object, found ") + model->type_name() + " " + shown(*model));
  check.knownKeys(*model, kModelKeys, at, "key");

  if (const Json* v = jsonMember(*model, "shape_memory")) {
    if (v->is_boolean() && !v->get<bool>()) {
      m.shapeMemory.reset();
    } else {
      if (!v->is_string() || (v->get<std::string>() != "template" && v->get<std::string>() != "smoothing"))
        check.fail(at, "\"shape_memory\" must be \"template\", \"smoothing\" or false, found " + shown(*v));
      m.shapeMemory = v->get<std::string>() == "template" ? InternalMode::ShapeMemory : InternalMode::Smoothing;
    }
  }
  const bool stiffness = check.numberIn(*model, "internal_stiffness", 0.0, 1.0, false, at, &m.internalStiffness);
  if (stiffness && !m.shapeMemory)
    check.fail(at, "\"internal_stiffness\" is given but \"shape_memory\" is false (no internal constraint)");

  if (const Json* v = jsonMember(*model, "global_prior")) {
    const std::vector<std::string> priors = {"rigid", "similarity", "affine"};
    if (v->is_boolean() && !v->get<bool>()) {
      m.globalPrior = false;
      m.priorTransform.reset();
    } else {
      const auto it = v->is_string() ? std::find(priors.begin(), priors.end(), v->get<std::string>()) : priors.end();
      if (it == priors.end())
        check.fail(at, "\"global_prior\" must be one of rigid, similarity, affine or false, found " + shown(*v));
      m.globalPrior = true;
      m.priorTransform = it == priors.begin()       ? PriorTransform::Rigid
                         : it == priors.begin() + 1 ? PriorTransform::Similarity
                                                    : PriorTransform::Affine;
    }
  }

  const int force = check.choice(o, "force", kForces, where, false);
  const int imageForce = check.choice(*model, "image_force", kForces, at, false);
  if (imageForce >= 0 && force >= 0)
    check.fail(where, "both \"force\" and model \"image_force\" are given (they are synonyms: keep one)");
  if (const int f = imageForce >= 0 ? imageForce : force; f >= 0) {
    m.imageForce = static_cast<TargetMode>(f);
    obj.hasForce = true;
    obj.force = m.imageForce;
  }

  check.boolean(*model, "medial_axis", at, &m.medialAxis);
  const bool radial = check.numberIn(*model, "radial_stiffness", 0.0, 1.0, false, at, &m.radialStiffness);
  const bool spacing = check.numberIn(*model, "axis_spacing_mm", 0.5, 100.0, false, at, &m.axisSpacingMm);
  if ((radial || spacing) && !m.medialAxis)
    check.fail(at, std::string("\"") + (radial ? "radial_stiffness" : "axis_spacing_mm") +
                       "\" is given but the object has no medial axis (set \"medial_axis\": true)");
  bool axisFirst = false;
  if (check.boolean(*model, "axis_first", at, &axisFirst)) {
    if (!m.medialAxis)
      check.fail(at, "\"axis_first\" is given but the object has no medial axis (set \"medial_axis\": true)");
    m.axisFirst = axisFirst;
  }
  bool refine = false;
  if (check.boolean(*model, "refine", at, &refine)) m.refine = refine;
  bool remesh = false;
  if (check.boolean(*model, "remesh", at, &remesh)) m.remesh = remesh;

  check.boolean(*model, "volumetric", at, &m.volumetric);
  if (check.numberIn(*model, "volume_stiffness", 0.0, 1.0, false, at, &m.volumeStiffness) && !m.volumetric)
    check.fail(at, "\"volume_stiffness\" is given but the object has no volume model (set \"volumetric\": true)");
  return m;
}

/// The object's optional "profiles_from" entry into obj.profileSource and obj.profileImagePath: {"mirror_x": c} or
/// {"matrix": [[a, b, c, d] × 4]} as the affine map from template coordinates to where the profiles are learned, and
/// {"image": path} for an image of its own to learn them on (relative to the scene's folder); at least one of the
/// three, at most one of the first two. Only with the profile force.
void parseProfileSource(const Checker& check, const Json& o, const std::string& where, const fs::path& folder,
                        SceneObject& obj) {
  const Json* v = jsonMember(o, "profiles_from");
  if (!v) return;
  const std::string at = where + " profiles_from";
  if (!v->is_object())
    check.fail(at, std::string("expected {\"mirror_x\": x_mm}, {\"matrix\": 4x4} and/or {\"image\": path}, found ") +
                       v->type_name() + " " + shown(*v));
  check.knownKeys(*v, {"mirror_x", "matrix", "image", "subjects"}, at, "key");
  const Json* mirror = jsonMember(*v, "mirror_x");
  const Json* matrix = jsonMember(*v, "matrix");
  auto inFolder = [&folder](const std::string& name) {
    const fs::path file(name);
    return (file.is_absolute() ? file : folder / file).lexically_normal().string();
  };
  if (const Json* subjects = jsonMember(*v, "subjects")) {
    if (!subjects->is_array() || subjects->empty())
      check.fail(at, "\"subjects\" must be a non-empty array of {\"image\": path, \"surface\": path}, found " +
                         shown(*subjects));
    for (size_t k = 0; k < subjects->size(); ++k) {
      const Json& e = (*subjects)[k];
      const std::string here = at + " subjects[" + std::to_string(k) + "]";
      if (!e.is_object())
        check.fail(here, std::string("expected {\"image\": path, \"surface\": path}, found ") + shown(e));
      check.knownKeys(e, {"image", "surface"}, here, "key");
      SceneObject::Subject s;
      s.imagePath = inFolder(*check.string(e, "image", here, true));
      s.surfacePath = inFolder(*check.string(e, "surface", here, true));
      obj.profileSubjects.push_back(std::move(s));
    }
    obj.profileImagePath = obj.profileSubjects.front().imagePath;
  }
  if (const std::string* image = check.string(*v, "image", at, false)) obj.profileImagePath = inFolder(*image);
  if (mirror && matrix) check.fail(at, "give at most one of \"mirror_x\" and \"matrix\"");
  if (!mirror && !matrix && obj.profileImagePath.empty()) check.fail(at, "give \"mirror_x\", \"matrix\" or \"image\"");
  if (obj.model.imageForce != TargetMode::Profile)
    check.fail(where,
               "\"profiles_from\" is given but the image force is gradient (profiles are learned only by the "
               "profile force: set \"force\": \"profile\")");
  if (!mirror && !matrix) return;
  Eigen::Matrix4d p = Eigen::Matrix4d::Identity();
  if (mirror) {
    // x' = 2c − x: the reflection about the plane x = c (RAS mm).
    if (!mirror->is_number() || !std::isfinite(mirror->get<double>()))
      check.fail(at, "\"mirror_x\" must be a finite number (mm), found " + shown(*mirror));
    p(0, 0) = -1;
    p(0, 3) = 2 * mirror->get<double>();
  } else {
    const char* shape = "\"matrix\" must be 4 rows of 4 finite numbers with last row 0 0 0 1, found ";
    if (!matrix->is_array() || matrix->size() != 4) check.fail(at, shape + shown(*matrix));
    for (int r = 0; r < 4; ++r) {
      const Json& row = (*matrix)[static_cast<size_t>(r)];
      if (!row.is_array() || row.size() != 4) check.fail(at, shape + shown(row));
      for (int c = 0; c < 4; ++c) {
        const Json& x = row[static_cast<size_t>(c)];
        if (!x.is_number() || !std::isfinite(x.get<double>())) check.fail(at, shape + shown(row));
        p(r, c) = x.get<double>();
      }
    }
    if (p.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) check.fail(at, shape + shown((*matrix)[3]));
    // Invertible, relative to the matrix's scale (|det A| against the product of its row lengths).
    const Eigen::Matrix3d a = p.topLeftCorner<3, 3>();
    const double scale = a.row(0).norm() * a.row(1).norm() * a.row(2).norm();
    if (!(std::abs(a.determinant()) > 1e-9 * scale))
      check.fail(at, "\"matrix\" is singular (its 3x3 part has no inverse)");
  }
  obj.profileSource = p;
}

/// The optional pair parameters of a collision entry (object form) into `p`.
void parsePairParameters(const Checker& check, const Json& e, const std::string& where, CollisionPair& p) {
  // The ranges of --collision-gap and --collision-proximity.
  check.numberIn(e, "gap_mm", 0.0, 10.0, false, where, &p.gapMm);
  check.numberIn(e, "proximity_mm", 0.0, 50.0, true, where, &p.proximityMm);
  check.numberIn(e, "friction", 0.0, 1.0, false, where, &p.friction);
  if (const int m = check.choice(e, "mode", {"position", "velocity", "acceleration"}, where, false); m >= 0)
    p.mode = static_cast<CollisionMode>(m);
  if (const int t = check.choice(e, "target", {"spring", "reaction", "reference"}, where, false); t >= 0)
    p.target = static_cast<CollisionTarget>(t);
  if (const int r = check.choice(e, "resolution", {"sequential", "global"}, where, false); r >= 0)
    p.resolution = static_cast<CollisionResolution>(r);
}

/// Object `i` of the scene's "objects" (every key checked; its template not read yet). `byName` and `byLabel` record
/// the objects before it (duplicates are errors).
SceneObject parseObject(const Checker& check, const Json& o, size_t i, const fs::path& folder, const Scene& scene,
                        std::map<std::string, size_t>& byName, std::map<int, size_t>& byLabel) {
  const std::vector<std::string> kinds = {"bone", "muscle", "generic"};
  const std::vector<std::string> polarities = {"auto", "dark-inside", "bright-inside"};
  if (!o.is_object()) check.fail(objectWhere(i, ""), std::string("expected an object, found ") + o.type_name());
  // The name first, so that every later message can show it.
  std::string name;
  if (const Json* n = jsonMember(o, "name"); n && n->is_string()) name = n->get<std::string>();
  const std::string where = objectWhere(i, printableName(name));
  check.knownKeys(o, kObjectKeys, where, "key");

  SceneObject obj;
  obj.name = *check.string(o, "name", where, true);
  if (!isSafeName(obj.name))
    check.fail(where,
               "the name must be 1-64 characters of letters, digits, '_', '.' or '-', starting with a letter or digit "
               "(it names the output files)");
  if (auto it = byName.find(obj.name); it != byName.end())
    check.fail(where, "duplicate name \"" + obj.name + "\" (also " + objectWhere(it->second, obj.name) + ")");
  byName[obj.name] = i;

  const Json* label = jsonMember(o, "label");
  if (!label) check.fail(where, "missing key \"label\"");
  if (!label->is_number() || label->get<double>() != std::floor(label->get<double>()) || label->get<double>() < 1 ||
      label->get<double>() > 32767)
    check.fail(where, "\"label\" must be an integer in 1..32767, found " + shown(*label));
  obj.label = jsonInt(*label);
  if (auto it = byLabel.find(obj.label); it != byLabel.end())
    check.fail(where, "duplicate label " + std::to_string(obj.label) + " (also " +
                          objectWhere(it->second, scene.objects[it->second].name) + ")");
  byLabel[obj.label] = i;

  obj.kind = static_cast<ObjectKind>(check.choice(o, "kind", kinds, where, true));
  if (const Json* colour = jsonMember(o, "colour")) {
    bool ok = colour->is_array() && colour->size() == 3;
    for (size_t c = 0; ok && c < 3; ++c) {
      const Json& v = (*colour)[c];
      ok = v.is_number() && v.get<double>() == std::floor(v.get<double>()) && v.get<double>() >= 0 &&
           v.get<double>() <= 255;
    }
    if (!ok) check.fail(where, "\"colour\" must be [r, g, b] with integers 0..255, found " + shown(*colour));
    obj.colour = std::array<int, 3>{jsonInt((*colour)[0]), jsonInt((*colour)[1]), jsonInt((*colour)[2])};
  }
  const fs::path templ(*check.string(o, "template", where, true));
  obj.templatePath = (templ.is_absolute() ? templ : folder / templ).lexically_normal().string();
  if (const int p = check.choice(o, "polarity", polarities, where, false); p >= 0) {
    obj.hasPolarity = true;
    obj.polarity = p == 0 ? Polarity::Auto : p == 1 ? Polarity::DarkInside : Polarity::BrightInside;
  }
  obj.model = parseModel(check, o, where, obj);
  parseProfileSource(check, o, where, folder, obj);
  return obj;
}

/// The scene's objects, checked in file order before any template is read (cheap errors first).
void parseObjects(const Checker& check, const Json& json, const std::string& path, Scene& scene) {
  const Json* objects = jsonMember(json, "objects");
  if (!objects) check.fail("", "missing key \"objects\"");
  if (!objects->is_array()) check.fail("", std::string("\"objects\" must be an array, found ") + objects->type_name());
  if (objects->empty()) check.fail("", "\"objects\" is empty (a scene needs at least one object)");
  const fs::path folder = fs::path(path).parent_path();
  std::map<std::string, size_t> byName;
  std::map<int, size_t> byLabel;
  for (size_t i = 0; i < objects->size(); ++i)
    scene.objects.push_back(parseObject(check, (*objects)[i], i, folder, scene, byName, byLabel));
}

/// The scene's "collisions": the pairs declared by name (into scene.collisions) and the "auto" entry (into
/// scene.autoCollisions; its pairs are found once the templates are read). Returns the pairs declared by name.
std::map<std::pair<int, int>, size_t> parseCollisions(const Checker& check, const Json& json, Scene& scene) {
  std::map<std::pair<int, int>, size_t> declared;  // pair → entry that declared it
  std::map<std::string, size_t> byName;
  for (size_t i = 0; i < scene.objects.size(); ++i) byName[scene.objects[i].name] = i;
  bool wantAuto = false;
  double autoWithinMm = kAutoWithinMm;
  CollisionPair autoParameters;
  if (const Json* col = jsonMember(json, "collisions")) {
    if (col->is_string()) {
      if (col->get<std::string>() != "auto")
        check.fail("", "\"collisions\" must be an array or \"auto\", found " + shown(*col));
      wantAuto = true;
    } else if (!col->is_array()) {
      check.fail("", std::string("\"collisions\" must be an array or \"auto\", found ") + col->type_name());
    }
    const Json none = Json::array();
    const Json& entries = col->is_array() ? *col : none;
    size_t autoEntry = 0;
    auto names = [&] {
      std::vector<std::string> all;
      for (const auto& o : scene.objects) all.push_back(o.name);
      return joined(all);
    };
    for (size_t c = 0; c < entries.size(); ++c) {
      const Json& e = entries[c];
      std::string where = "collisions[" + std::to_string(c) + "]";
      if (e.is_object() && jsonMember(e, "auto")) {
        std::vector<std::string> known = {"auto", "within_mm"};
        known.insert(known.end(), kPairParameterKeys.begin(), kPairParameterKeys.end());
        check.knownKeys(e, known, where, "key");
        const Json& flag = *jsonMember(e, "auto");
        if (!flag.is_boolean() || !flag.get<bool>())
          check.fail(where, "\"auto\" must be true (leave the entry out for no automatic pairs), found " + shown(flag));
        if (wantAuto)
          check.fail(where, "a second \"auto\" entry (also collisions[" + std::to_string(autoEntry) + "]): keep one");
        wantAuto = true;
        autoEntry = c;
        check.numberIn(e, "within_mm", 0.0, 100.0, false, where, &autoWithinMm);
        parsePairParameters(check, e, where, autoParameters);
        continue;
      }
      const Json* pair = &e;
      if (e.is_object()) {
        if (!jsonMember(e, "pair"))
          check.fail(where, "an object entry needs \"pair\": [\"a\", \"b\"] or \"auto\": true");
        pair = jsonMember(e, "pair");
      }
      if (!pair->is_array() || pair->size() != 2 || !(*pair)[0].is_string() || !(*pair)[1].is_string())
        check.fail(where, "expected a pair of object names like [\"femur\", \"quadriceps\"], found " + shown(*pair));
      where += " (" + (*pair)[0].get<std::string>() + ", " + (*pair)[1].get<std::string>() + ")";
      int idx[2];
      for (int s = 0; s < 2; ++s) {
        const std::string& n = (*pair)[s].get<std::string>();
        auto it = byName.find(n);
        if (it == byName.end()) check.fail(where, "unknown object \"" + n + "\" (objects: " + names() + ")");
        idx[s] = static_cast<int>(it->second);
      }
      if (idx[0] == idx[1])
        check.fail(where, "an object cannot collide with itself (\"" + scene.objects[idx[0]].name + "\")");
      CollisionPair p;
      p.a = std::min(idx[0], idx[1]);
      p.b = std::max(idx[0], idx[1]);
      if (e.is_object()) {
        std::vector<std::string> known = {"pair"};
        known.insert(known.end(), kPairParameterKeys.begin(), kPairParameterKeys.end());
        check.knownKeys(e, known, where, "key");
        parsePairParameters(check, e, where, p);
      }
      const auto [it, fresh] = declared.emplace(std::make_pair(p.a, p.b), c);
      if (!fresh) check.fail(where, "pair declared twice (also collisions[" + std::to_string(it->second) + "])");
      scene.collisions.push_back(p);
    }
  }
  if (wantAuto) scene.autoCollisions = AutoCollisions{autoWithinMm, autoParameters};
  return declared;
}

/// Reads every object's template (SPACE tag honoured, closedness and templateProblem() checked), errors naming the
/// object.
void readTemplates(const Checker& check, Scene& scene) {
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& obj = scene.objects[i];
    // A mesh of the object, its reading error naming the object and what the mesh is to it.
    auto read = [&](const std::string& path, const std::string& what) {
      try {
        return readMesh(path);
      } catch (const IoError& e) {
        check.fail(objectWhere(i, obj.name), what + " " + e.file() + ": " + e.problem());
      } catch (const Error& e) {
        check.fail(objectWhere(i, obj.name), what + " " + path + ": " + e.what());
      }
    };
    obj.templ = read(obj.templatePath, "template");
    const std::string problem = templateProblem(obj.templ);
    if (!problem.empty()) check.fail(objectWhere(i, obj.name), "template " + obj.templatePath + ": " + problem);
    const bool inward = enclosedVolume(obj.templ) < 0;
    if (inward) {
      flipFaces(obj.templ);
      log::warn(obj.name + " (template " + obj.templatePath +
                "): the template is wound inward (negative enclosed volume); its faces were turned outward");
    }
    for (SceneObject::Subject& s : obj.profileSubjects) {
      s.surface = read(s.surfacePath, "profiles_from surface");
      // The template's points are carried onto the surface by vertex index: the same vertices, and no NaN.
      if (s.surface.vertexCount() != obj.templ.vertexCount() || !s.surface.vertices.allFinite())
        check.fail(objectWhere(i, obj.name),
                   "profiles_from surface " + s.surfacePath + ": " + std::to_string(s.surface.vertexCount()) +
                       " vertices, not the template's " + std::to_string(obj.templ.vertexCount()) +
                       " (a subject's surface is the template fitted onto that subject)");
      if (inward) flipFaces(s.surface);
    }
  }
}

/// Reads the images the objects learn their profiles on (each file once), errors naming the object.
void readProfileImages(const Checker& check, Scene& scene) {
  std::map<std::string, std::shared_ptr<const ImageF>> read;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& obj = scene.objects[i];
    if (obj.profileImagePath.empty()) continue;
    auto image = [&](const std::string& path, const char* what) {
      auto it = read.find(path);
      if (it == read.end()) {
        try {
          it = read.emplace(path, std::make_shared<ImageF>(readNifti<float>(path))).first;
        } catch (const IoError& e) {
          check.fail(objectWhere(i, obj.name), std::string(what) + " " + e.file() + ": " + e.problem());
        }
      }
      return it->second;
    };
    obj.profileImage = image(obj.profileImagePath, "profiles_from image");
    for (SceneObject::Subject& s : obj.profileSubjects) s.image = image(s.imagePath, "profiles_from subject image");
  }
}

/// The "auto" entry's pairs: every pair of templates within its distance (or overlapping) not declared by name.
void addAutoPairs(Scene& scene, const std::map<std::pair<int, int>, size_t>& declared) {
  if (scene.autoCollisions) {
    const double autoWithinMm = scene.autoCollisions->withinMm;
    const CollisionPair& autoParameters = scene.autoCollisions->parameters;
    std::vector<const TriangleMesh*> templates;
    for (const auto& o : scene.objects) templates.push_back(&o.templ);
    for (const auto& [a, b] : surfacesWithin(templates, autoWithinMm)) {
      if (declared.count({a, b})) continue;
      CollisionPair p = autoParameters;
      p.a = a;
      p.b = b;
      p.fromAuto = true;
      scene.collisions.push_back(p);
    }
  }
}

}  // namespace

ObjectModel defaultModel(ObjectKind k) {
  // Every kind gets what the segmenter does today; muscles will get a medial axis and a volume model (and possibly
  // the profile force) once the pipeline uses them: change it here, in one place.
  ObjectModel m;
  switch (k) {
    case ObjectKind::Bone:
    case ObjectKind::Muscle:
    case ObjectKind::Generic:
      m.shapeMemory = InternalMode::ShapeMemory;
      m.imageForce = TargetMode::Gradient;
      m.medialAxis = false;
      m.volumetric = false;
      break;
  }
  return m;
}

const char* objectKindName(ObjectKind k) {
  switch (k) {
    case ObjectKind::Bone:
      return "bone";
    case ObjectKind::Muscle:
      return "muscle";
    case ObjectKind::Generic:
      return "generic";
  }
  return "?";
}

std::optional<ObjectKind> parseObjectKind(const std::string& name) {
  for (ObjectKind k : {ObjectKind::Bone, ObjectKind::Muscle, ObjectKind::Generic})
    if (name == objectKindName(k)) return k;
  return std::nullopt;
}

Scene parseScene(const Json& json, const std::string& path) {
  const Checker check(path);
  if (!json.is_object()) check.fail("", std::string("a scene must be a JSON object, found ") + json.type_name());
  check.knownKeys(json, kTopKeys, "", "top-level key");
  Scene scene;
  scene.path = path;
  if (const std::string* d = check.string(json, "description", "", false)) scene.description = *d;
  if (const Json* v = jsonMember(json, "provenance")) {
    if (!v->is_object()) check.fail("", std::string("\"provenance\" must be an object, found ") + v->type_name());
    scene.provenance = *v;
  }
  parseObjects(check, json, path, scene);
  const std::map<std::pair<int, int>, size_t> declared = parseCollisions(check, json, scene);
  readTemplates(check, scene);
  readProfileImages(check, scene);
  addAutoPairs(scene, declared);
  return scene;
}

bool hasProfileSource(const SceneObject& obj) {
  return obj.profileSource.has_value() || obj.profileImage || !obj.profileImagePath.empty();
}

void toProfileSource(const SceneObject& obj, Points& positions, Points& normals) {
  if (!obj.profileSource) return;
  const Eigen::Matrix3d a = obj.profileSource->topLeftCorner<3, 3>();
  const Eigen::Vector3d t = obj.profileSource->topRightCorner<3, 1>();
  positions = (positions * a.transpose()).rowwise() + t.transpose();
  // Rows are nᵀ, so (A⁻ᵀn)ᵀ = nᵀA⁻¹. A⁻ᵀ maps the outward normal of the surface to the outward normal of its image
  // under any invertible A, mirrors included (the inside maps to the inside).
  normals = normals * a.inverse();
  for (Eigen::Index v = 0; v < normals.rows(); ++v) {
    const double len = normals.row(v).norm();
    if (len > 0) normals.row(v) /= len;
  }
}

Scene loadScene(const std::string& path) { return parseScene(readJsonFile(path), path); }

namespace {

/// The "model" keys of `m` that differ from the defaults of its kind (an empty object if none).
Json modelJson(const ObjectModel& m, ObjectKind kind) {
  const ObjectModel d = defaultModel(kind);
  Json j = Json::object();
  if (m.shapeMemory != d.shapeMemory)
    j["shape_memory"] =
        !m.shapeMemory ? Json(false) : Json(*m.shapeMemory == InternalMode::ShapeMemory ? "template" : "smoothing");
  if (m.internalStiffness >= 0) j["internal_stiffness"] = m.internalStiffness;
  if (!m.globalPrior) {
    j["global_prior"] = false;
  } else if (m.priorTransform) {
    j["global_prior"] = priorTransformName(*m.priorTransform);
  }
  if (m.medialAxis != d.medialAxis) j["medial_axis"] = m.medialAxis;
  if (m.radialStiffness >= 0) j["radial_stiffness"] = m.radialStiffness;
  if (m.axisSpacingMm > 0) j["axis_spacing_mm"] = m.axisSpacingMm;
  if (m.axisFirst) j["axis_first"] = *m.axisFirst;
  if (m.refine) j["refine"] = *m.refine;
  if (m.remesh) j["remesh"] = *m.remesh;
  if (m.volumetric != d.volumetric) j["volumetric"] = m.volumetric;
  if (m.volumeStiffness >= 0) j["volume_stiffness"] = m.volumeStiffness;
  return j;
}

/// {"mirror_x": c} for a mirror about x = c, else {"matrix": the 4×4 rows}.
Json profileSourceJson(const Eigen::Matrix4d& p) {
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  mirror(0, 3) = p(0, 3);
  Json j = Json::object();
  if (p == mirror) {
    j["mirror_x"] = 0.5 * p(0, 3);
    return j;
  }
  Json rows = Json::array();
  for (int r = 0; r < 4; ++r) rows.push_back(Json::array({p(r, 0), p(r, 1), p(r, 2), p(r, 3)}));
  j["matrix"] = rows;
  return j;
}

/// The optional parameters of a pair (or of the auto entry) into `j`; whether there were any.
bool pairParametersJson(const CollisionPair& p, Json& j) {
  const size_t before = j.size();
  if (p.gapMm >= 0) j["gap_mm"] = p.gapMm;
  if (p.proximityMm > 0) j["proximity_mm"] = p.proximityMm;
  if (p.friction >= 0) j["friction"] = p.friction;
  if (p.mode != CollisionMode::Position) j["mode"] = collisionModeName(p.mode);
  if (p.target != CollisionTarget::Spring) j["target"] = collisionTargetName(p.target);
  if (p.resolution) j["resolution"] = collisionResolutionName(*p.resolution);
  return j.size() > before;
}

/// `file` relative to `folder` when it lies below it, else absolute.
std::string pathFrom(const std::string& folder, const std::string& file) {
  const fs::path base = fs::absolute(folder.empty() ? "." : folder).lexically_normal();
  const fs::path rel = fs::absolute(file).lexically_normal().lexically_relative(base);
  if (rel.empty() || *rel.begin() == "..") return fs::absolute(file).lexically_normal().string();
  return rel.string();
}

}  // namespace

Json sceneJson(const Scene& scene, const std::string& folder) {
  Json out = Json::object();
  Json objects = Json::array();
  for (const SceneObject& o : scene.objects) {
    Json j = Json::object();
    j["name"] = o.name;
    j["label"] = o.label;
    j["kind"] = objectKindName(o.kind);
    if (o.colour) j["colour"] = Json::array({(*o.colour)[0], (*o.colour)[1], (*o.colour)[2]});
    j["template"] = pathFrom(folder, o.templatePath);
    if (o.hasPolarity) j["polarity"] = polarityName(o.polarity);
    if (o.hasForce) j["force"] = kForces[static_cast<size_t>(o.force)];
    if (const Json model = modelJson(o.model, o.kind); !model.empty()) j["model"] = model;
    if (o.profileSource || !o.profileImagePath.empty()) {
      Json source = o.profileSource ? profileSourceJson(*o.profileSource) : Json::object();
      if (!o.profileImagePath.empty()) source["image"] = pathFrom(folder, o.profileImagePath);
      if (!o.profileSubjects.empty()) {
        Json subjects = Json::array();
        for (const SceneObject::Subject& s : o.profileSubjects)
          subjects.push_back({{"image", pathFrom(folder, s.imagePath)}, {"surface", pathFrom(folder, s.surfacePath)}});
        source["subjects"] = subjects;
      }
      j["profiles_from"] = source;
    }
    objects.push_back(j);
  }
  out["objects"] = objects;
  Json collisions = Json::array();
  for (const CollisionPair& p : scene.collisions) {
    if (p.fromAuto) continue;
    const Json names =
        Json::array({scene.objects[static_cast<size_t>(p.a)].name, scene.objects[static_cast<size_t>(p.b)].name});
    Json entry = Json::object();
    entry["pair"] = names;
    collisions.push_back(pairParametersJson(p, entry) ? entry : names);
  }
  if (scene.autoCollisions) {
    Json entry = Json::object();
    entry["auto"] = true;
    entry["within_mm"] = scene.autoCollisions->withinMm;
    const bool parameters = pairParametersJson(scene.autoCollisions->parameters, entry);
    const bool plain = !parameters && scene.autoCollisions->withinMm == kAutoWithinMm;
    if (collisions.empty() && plain)
      out["collisions"] = "auto";
    else
      collisions.push_back(entry);
  }
  if (!collisions.empty()) out["collisions"] = collisions;
  if (!scene.description.empty()) out["description"] = scene.description;
  if (scene.provenance.is_object()) out["provenance"] = scene.provenance;
  return out;
}

void writeScene(const Scene& scene, const std::string& path) {
  writeJsonFile(path, sceneJson(scene, fs::path(path).parent_path().string()));
}

}  // namespace msk
