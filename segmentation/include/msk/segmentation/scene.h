#pragma once
/// Scenes: the objects to segment (name, label, kind, template, the constraints each gets) and their collision
/// pairs (declared, or "auto" from template proximity), read from scene.json.
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "msk/core/collision_response.h"
#include "msk/core/shape_matching_constraint.h"
#include "msk/core/simplex_internal_constraint.h"
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/json.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/image_forces.h"

namespace msk {

/// What an object is; sets defaults (bones: gradient force, stiffer shape memory; muscles: profile force...).
enum class ObjectKind { Bone, Muscle, Generic };

/// "bone" | "muscle" | "generic".
const char* objectKindName(ObjectKind k);
/// The kind objectKindName() names `name`; nullopt for any other string.
std::optional<ObjectKind> parseObjectKind(const std::string& name);

/// The constraints an object gets (scene key "model" of an object). Fields marked "< 0" or "unset" take the run's
/// value (SegmentOptions or the module's default), so a scene only states what it changes.
struct ObjectModel {
  /// "shape_memory": "template" → InternalMode::ShapeMemory, "smoothing" → InternalMode::Smoothing, false → unset
  /// (no internal constraint).
  std::optional<InternalMode> shapeMemory = InternalMode::ShapeMemory;
  double internalStiffness = -1;  ///< "internal_stiffness": γ of the internal constraint, [0, 1]; < 0 = run default
  bool globalPrior = true;        ///< false ("global_prior": false): no global shape prior
  std::optional<PriorTransform> priorTransform;  ///< "global_prior": "rigid"|"similarity"|"affine"; unset = run's
  TargetMode imageForce = TargetMode::Gradient;  ///< "image_force" (or the object-level synonym "force")
  bool medialAxis = false;      ///< "medial_axis": a 1-simplex medial axis with two-way radial constraints
  double radialStiffness = -1;  ///< "radial_stiffness": γ of the radial constraints, [0, 1]; < 0 = run default
  double axisSpacingMm = -1;    ///< "axis_spacing_mm": distance between axis vertices, mm, > 0; < 0 = run default
  /// "axis_first": run the axis-first coarse stage (the object moves as a generalised cylinder of its axis before its
  /// full-surface evolution; needs "medial_axis"); unset = the run's (AxisOptions::first)
  std::optional<bool> axisFirst;
  /// "refine": the object takes part in the refinement pass (ImageSearchOptions::refinePass: its converged surface as
  /// its reference shape, the gradient force with the edge level); unset = the run's
  std::optional<bool> refine;
  /// "remesh": the template is remeshed isotropically before the evolution (SurfaceOptions::remeshTemplates); false
  /// keeps its own triangulation (the output is then on it); unset = the run's for muscles and generic objects, kept
  /// for bones (segmenter.h)
  std::optional<bool> remesh;
  bool volumetric = false;      ///< "volumetric": a coupled 3-simplex volume model
  double volumeStiffness = -1;  ///< "volume_stiffness": γ of the 3-simplex internal constraint, [0, 1]; < 0 = run's
};

/// The model an object of kind `k` gets when its scene entry says nothing (the one place defaults by kind live).
/// Today every kind gets what the segmenter has always done: template shape memory, the run's global prior, gradient
/// image force, no medial axis, no volume model.
ObjectModel defaultModel(ObjectKind k);

/// One object of a scene.
struct SceneObject {
  std::string name;                       ///< unique, non-empty
  int label = 0;                          ///< value in the output label map, 1..32767, unique
  ObjectKind kind = ObjectKind::Generic;  ///< bone | muscle | generic
  /// Display colour (scene key "colour": [r, g, b], 0..255 each) for the label tables and QC pictures; unset: the
  /// QC palette's colour of the object's place in the scene (objectColour()).
  std::optional<std::array<int, 3>> colour;
  std::string templatePath;  ///< resolved path of the template mesh
  TriangleMesh templ;        ///< the template, RAS mm (closed, loaded and checked)
  /// Optional per-object overrides (scene keys "polarity": "auto|dark-inside|bright-inside",
  /// "force": "gradient|profile", or its synonym "image_force" in "model"); unset keys keep the kind's defaults.
  bool hasPolarity = false;
  Polarity polarity = Polarity::Auto;  ///< valid if hasPolarity
  bool hasForce = false;
  TargetMode force = TargetMode::Gradient;  ///< valid if hasForce (also in model.imageForce)
  ObjectModel model;                        ///< defaultModel(kind) with the object's "model" keys applied
  /// Where the profile force learns its intensity profiles (scene key "profiles_from"): a 4×4 affine map P from
  /// template coordinates (RAS mm) to the place the template was taken from, e.g. the contralateral structure it was
  /// mirrored from. Profiles are then learned at P·x with normals A⁻ᵀn (A = P's 3×3 part), normalised and kept
  /// outward even when P mirrors. {"mirror_x": c} is the mirror about the plane x = c mm; {"matrix": [[4 numbers]
  /// × 4]} any invertible affine map (last row 0 0 0 1). Unset: profiles are learned on the template itself. Only
  /// allowed with the profile image force; the source must lie inside the image (or inside profileImage).
  std::optional<Eigen::Matrix4d> profileSource;
  /// {"image": path} in "profiles_from": the image the profiles are learned on instead of the one segmented (an
  /// atlas's reference image, whose world the template and profileSource then refer to); empty: the segmented image.
  std::string profileImagePath;
  std::shared_ptr<const ImageF> profileImage;  ///< read by loadScene(), shared by the objects naming the same file
  /// {"subjects": [{"image": path, "surface": path}, ...]} in "profiles_from" (an atlas of several subjects): the
  /// profiles are learned on each subject's image where the template's points lie on that subject's surface, and
  /// averaged. Each surface is the template fitted onto that subject (the template's vertex count and order; in the
  /// subject image's world, which profileSource maps into as it does into profileImage's). profileImage is the first
  /// subject's image unless "image" names another.
  struct Subject {
    std::string imagePath, surfacePath;
    std::shared_ptr<const ImageF> image;
    TriangleMesh surface;
  };
  std::vector<Subject> profileSubjects;
};

// CollisionMode, CollisionTarget and CollisionResolution (with their names) live in msk/core/collision_response.h.

/// One collision pair of a scene. Parameters < 0 take the run's value (SegmentOptions).
struct CollisionPair {
  int a = 0, b = 0;                              ///< object indices, a < b
  double gapMm = -1;                             ///< "gap_mm": clearance g kept between the partners, mm, ≥ 0
  double proximityMm = -1;                       ///< "proximity_mm": contact search reach d_max beyond the gap, mm, > 0
  double friction = -1;                          ///< "friction": μ ∈ [0, 1]
  CollisionMode mode = CollisionMode::Position;  ///< "mode": "position" | "velocity" | "acceleration"
  CollisionTarget target = CollisionTarget::Spring;  ///< "target": "spring" | "reaction" | "reference"
  /// "resolution": "sequential" | "global"; unset = the run's (CollisionOptions::resolution)
  std::optional<CollisionResolution> resolution = std::nullopt;
  bool fromAuto = false;  ///< found by an "auto" entry (templates within its distance), not declared by name
};

/// The "auto" entry of a scene's collisions: every pair of objects whose templates come within `withinMm` of each
/// other (or overlap), with the pair parameters of `parameters` (its object indices unused).
struct AutoCollisions {
  double withinMm = 2.0;     ///< "within_mm", ≥ 0
  CollisionPair parameters;  ///< "gap_mm", "proximity_mm", "friction", "mode", "target", "resolution"
};

/// A scene: objects and declared collision pairs (indices into objects).
struct Scene {
  std::string path;                              ///< the scene file
  std::vector<SceneObject> objects;              ///< in file order
  std::vector<CollisionPair> collisions;         ///< declared pairs in file order, then auto pairs; no duplicates
  std::optional<AutoCollisions> autoCollisions;  ///< the "auto" entry, if the scene has one
  std::string description;                       ///< "description": free text (optional)
  /// "provenance": what made the scene (a generator's name and parameters, source files), kept as given; null if
  /// absent, else a JSON object.
  Json provenance;
};

/// Whether `obj` has somewhere to learn its profiles other than its template where it starts: a "profiles_from" map
/// (profileSource) or image (profileImage).
bool hasProfileSource(const SceneObject& obj);

/// Maps template points and their outward normals to where `obj` learns its profiles (obj.profileSource; unchanged if
/// unset): positions P·x, normals A⁻ᵀn normalised, which stay outward when P mirrors. Zero normals stay zero.
void toProfileSource(const SceneObject& obj, Points& positions, Points& normals);

/// Reads and validates a scene. Template paths are relative to the scene file. Unknown keys, wrong types, values out
/// of range, missing keys, duplicate names or labels, unknown collision names, a pair declared twice, unreadable or
/// non-closed templates → IoError naming the scene file, the key and the object (e.g. "objects[1] (quadriceps):
/// unknown key \"lable\"").
///
/// "collisions" is an array whose entries are ["a", "b"], {"pair": ["a", "b"], <parameters>} or one
/// {"auto": true, "within_mm": D, <parameters>} (D ≥ 0, default 2) that adds every pair of objects whose templates
/// come within D mm of each other or overlap (surfaceSeparationMm), except pairs declared by name, which keep their
/// own parameters. <parameters> are the optional "gap_mm", "proximity_mm", "friction", "mode", "target",
/// "resolution".
/// "collisions": "auto" is short for [{"auto": true, "within_mm": 2}].
Scene loadScene(const std::string& path);

/// Parses a scene from JSON text already read (`path` used for messages and relative template paths).
Scene parseScene(const Json& json, const std::string& path);

/// The scene as scene.json holds it, the inverse of parseScene(): each object's name, label, kind, template path
/// (relative to `folder`, the folder the file will be in, where the template lies below it), its polarity and force
/// if set, its "model" keys where they differ from defaultModel(kind), its "profiles_from" matrix; the pairs declared
/// by name and the "auto" entry; description and provenance.
Json sceneJson(const Scene& scene, const std::string& folder);

/// Writes sceneJson(scene, the folder of `path`) to `path` atomically.
void writeScene(const Scene& scene, const std::string& path);

}  // namespace msk
