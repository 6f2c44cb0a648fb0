#pragma once
/// Scenes: the objects to segment (name, label, kind, template) and their collision pairs, read from scene.json.
#include <string>
#include <utility>
#include <vector>

#include "msk/core/json.h"
#include "msk/core/triangle_mesh.h"
#include "msk/segmentation/image_forces.h"

namespace msk {

/// What an object is; sets defaults (bones: gradient force, stiffer shape memory; muscles: profile force...).
enum class ObjectKind { Bone, Muscle, Generic };

/// "bone" | "muscle" | "generic".
const char* objectKindName(ObjectKind k);

/// One object of a scene.
struct SceneObject {
  std::string name;                       ///< unique, non-empty
  int label = 0;                          ///< value in the output label map, 1..32767, unique
  ObjectKind kind = ObjectKind::Generic;  ///< bone | muscle | generic
  std::string templatePath;               ///< resolved path of the template mesh
  TriangleMesh templ;                     ///< the template, RAS mm (closed, loaded and checked)
  /// Optional per-object overrides (scene keys "polarity": "auto|dark-inside|bright-inside",
  /// "force": "gradient|profile"); unset keys keep the kind's defaults.
  bool hasPolarity = false;
  Polarity polarity = Polarity::Auto;  ///< valid if hasPolarity
  bool hasForce = false;
  TargetMode force = TargetMode::Gradient;  ///< valid if hasForce
};

/// A scene: objects and declared collision pairs (indices into objects).
struct Scene {
  std::string path;                               ///< the scene file
  std::vector<SceneObject> objects;               ///< in file order
  std::vector<std::pair<int, int>> collisions;    ///< pairs of object indices, i < j, no duplicates
  Json metadata;                                  ///< the optional "phantom"/"description" entries, kept as given
};

/// Reads and validates a scene. Template paths are relative to the scene file. Unknown keys, wrong types, missing
/// keys, duplicate names or labels, unknown collision names, unreadable or non-closed templates → IoError naming the
/// scene file, the key and the object (e.g. "objects[1] (quadriceps): unknown key \"lable\"").
Scene loadScene(const std::string& path);

/// Parses a scene from JSON text already read (`path` used for messages and relative template paths).
Scene parseScene(const Json& json, const std::string& path);

}  // namespace msk
