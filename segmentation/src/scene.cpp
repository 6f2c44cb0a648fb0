#include "msk/segmentation/scene.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>

#include "msk/core/error.h"
#include "msk/imaging/mesh_io.h"

namespace fs = std::filesystem;

namespace msk {

namespace {

const std::vector<std::string> kTopKeys = {"objects", "collisions", "phantom", "description"};
const std::vector<std::string> kObjectKeys = {"name", "label", "kind", "template", "polarity", "force"};

std::string joined(const std::vector<std::string>& words) {
  std::string s;
  for (const auto& w : words) s += (s.empty() ? "" : ", ") + w;
  return s;
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
    for (const auto& kv : obj.asObject())
      if (std::find(known.begin(), known.end(), kv.first) == known.end())
        fail(where, std::string("unknown ") + what + " \"" + kv.first + "\" (known: " + joined(known) + ")");
  }
  /// A string member, required or optional (nullptr if absent and optional).
  const std::string* string(const Json& obj, const std::string& key, const std::string& where, bool required) const {
    const Json* v = obj.find(key);
    if (!v) {
      if (required) fail(where, "missing key \"" + key + "\"");
      return nullptr;
    }
    if (!v->isString()) fail(where, "\"" + key + "\" must be a string, found " + v->typeName() + " " + shown(*v));
    if (v->asString().empty()) fail(where, "\"" + key + "\" must not be empty");
    return &v->asString();
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

 private:
  std::string path_;
};

std::string objectWhere(size_t i, const std::string& name) {
  std::string w = "objects[" + std::to_string(i) + "]";
  if (!name.empty()) w += " (" + name + ")";
  return w;
}

}  // namespace

const char* objectKindName(ObjectKind k) {
  switch (k) {
    case ObjectKind::Bone: return "bone";
    case ObjectKind::Muscle: return "muscle";
    case ObjectKind::Generic: return "generic";
  }
  return "?";
}

Scene parseScene(const Json& json, const std::string& path) {
  const Checker check(path);
  if (!json.isObject()) check.fail("", std::string("a scene must be a JSON object, found ") + json.typeName());
  check.knownKeys(json, kTopKeys, "", "top-level key");

  Scene scene;
  scene.path = path;
  scene.metadata = Json::object();
  for (const char* key : {"phantom", "description"})
    if (const Json* v = json.find(key)) scene.metadata[key] = *v;

  // Objects: every key checked first (cheap errors before any template is read).
  const Json* objects = json.find("objects");
  if (!objects) check.fail("", "missing key \"objects\"");
  if (!objects->isArray()) check.fail("", std::string("\"objects\" must be an array, found ") + objects->typeName());
  if (objects->asArray().empty()) check.fail("", "\"objects\" is empty (a scene needs at least one object)");
  const fs::path folder = fs::path(path).parent_path();
  std::map<std::string, size_t> byName;
  std::map<int, size_t> byLabel;
  const std::vector<std::string> kinds = {"bone", "muscle", "generic"};
  const std::vector<std::string> polarities = {"auto", "dark-inside", "bright-inside"};
  const std::vector<std::string> forces = {"gradient", "profile"};
  for (size_t i = 0; i < objects->asArray().size(); ++i) {
    const Json& o = objects->asArray()[i];
    if (!o.isObject()) check.fail(objectWhere(i, ""), std::string("expected an object, found ") + o.typeName());
    // The name first, so that every later message can show it.
    std::string name;
    if (const Json* n = o.find("name"); n && n->isString()) name = n->asString();
    const std::string where = objectWhere(i, name);
    check.knownKeys(o, kObjectKeys, where, "key");

    SceneObject obj;
    obj.name = *check.string(o, "name", where, true);
    if (auto it = byName.find(obj.name); it != byName.end())
      check.fail(where, "duplicate name \"" + obj.name + "\" (also " + objectWhere(it->second, obj.name) + ")");
    byName[obj.name] = i;

    const Json* label = o.find("label");
    if (!label) check.fail(where, "missing key \"label\"");
    if (!label->isNumber() || label->asNumber() != std::floor(label->asNumber()) || label->asNumber() < 1 ||
        label->asNumber() > 32767)
      check.fail(where, "\"label\" must be an integer in 1..32767, found " + shown(*label));
    obj.label = label->asInt();
    if (auto it = byLabel.find(obj.label); it != byLabel.end())
      check.fail(where, "duplicate label " + std::to_string(obj.label) + " (also " +
                            objectWhere(it->second, scene.objects[it->second].name) + ")");
    byLabel[obj.label] = i;

    obj.kind = static_cast<ObjectKind>(check.choice(o, "kind", kinds, where, true));
    const fs::path templ(*check.string(o, "template", where, true));
    obj.templatePath = (templ.is_absolute() ? templ : folder / templ).lexically_normal().string();
    if (const int p = check.choice(o, "polarity", polarities, where, false); p >= 0) {
      obj.hasPolarity = true;
      obj.polarity = p == 0 ? Polarity::Auto : p == 1 ? Polarity::DarkInside : Polarity::BrightInside;
    }
    if (const int f = check.choice(o, "force", forces, where, false); f >= 0) {
      obj.hasForce = true;
      obj.force = f == 0 ? TargetMode::Gradient : TargetMode::Profile;
    }
    scene.objects.push_back(std::move(obj));
  }

  // Collisions: pairs of distinct known names; duplicates in either order collapse to one pair (i < j).
  if (const Json* col = json.find("collisions")) {
    if (!col->isArray()) check.fail("", std::string("\"collisions\" must be an array, found ") + col->typeName());
    std::set<std::pair<int, int>> seen;
    for (size_t c = 0; c < col->asArray().size(); ++c) {
      const Json& pair = col->asArray()[c];
      const std::string where = "collisions[" + std::to_string(c) + "]";
      if (!pair.isArray() || pair.size() != 2 || !pair.asArray()[0].isString() || !pair.asArray()[1].isString())
        check.fail(where, "expected a pair of object names like [\"femur\", \"quadriceps\"], found " + shown(pair));
      int idx[2];
      for (int s = 0; s < 2; ++s) {
        const std::string& n = pair.asArray()[s].asString();
        auto it = byName.find(n);
        if (it == byName.end()) {
          std::vector<std::string> names;
          for (const auto& o : scene.objects) names.push_back(o.name);
          check.fail(where, "unknown object \"" + n + "\" (objects: " + joined(names) + ")");
        }
        idx[s] = static_cast<int>(it->second);
      }
      if (idx[0] == idx[1])
        check.fail(where, "an object cannot collide with itself (\"" + scene.objects[idx[0]].name + "\")");
      const std::pair<int, int> p(std::min(idx[0], idx[1]), std::max(idx[0], idx[1]));
      if (seen.insert(p).second) scene.collisions.push_back(p);
    }
  }

  // Templates last: read (SPACE tag honoured, closedness checked) and errors wrapped to name the object.
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& obj = scene.objects[i];
    try {
      obj.templ = readMesh(obj.templatePath);
    } catch (const IoError& e) {
      check.fail(objectWhere(i, obj.name), "template " + e.file() + ": " + e.problem());
    } catch (const Error& e) {
      check.fail(objectWhere(i, obj.name), "template " + obj.templatePath + ": " + e.what());
    }
  }
  return scene;
}

Scene loadScene(const std::string& path) { return parseScene(Json::readFile(path), path); }

}  // namespace msk
