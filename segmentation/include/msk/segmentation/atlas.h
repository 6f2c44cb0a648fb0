#pragma once
/// Atlases: a reference subject's image, one template per structure and the scene that evolves them, in one folder
/// (atlas.json, reference.nii.gz, template_<name>.vtk, scene.json); and the placement of an atlas in a new subject's
/// image by registration (global, then per object), which turns the atlas's scene into one for that subject.
#include <Eigen/Core>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "msk/core/log.h"
#include "msk/imaging/json.h"
#include "msk/imaging/registration.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"
#include "msk/segmentation/template_builder.h"

namespace msk {

/// The atlas format this build writes and reads (atlas.json "format_version").
constexpr int kAtlasFormatVersion = 2;
/// The oldest atlas format this build reads (version 1: one subject; 2 adds several subjects).
constexpr int kAtlasOldestFormatVersion = 1;

/// One structure of an atlas to build.
struct AtlasObjectSpec {
  std::string name;
  int label = 0;
  ObjectKind kind = ObjectKind::Generic;
};

/// Parses "NAME:LABEL[:KIND],..." (KIND bone|muscle|generic, default generic). Throws ParameterError naming
/// `option` for a malformed entry, a label out of 1..32767, an unknown kind, or a duplicate name or label.
std::vector<AtlasObjectSpec> parseAtlasObjects(const std::string& text, const std::string& option = "--objects");

/// How an atlas's scene pairs its objects.
enum class AtlasCollisions {
  Auto,  ///< every pair whose templates come within 2 mm (scene "collisions": "auto")
  All,   ///< every pair declared
  None   ///< no collision pairs
};

/// Which templates an atlas of several subjects makes the subjects' mean shape.
enum class AtlasShape {
  /// Bones: the mean (every phantom femur of twelve gained 0.005–0.016 Dice); muscles and generic objects: the
  /// reference's own (their mean over four phantoms lost 0.01 on average: a compartment's edges averaged over subjects
  /// whose septa lie elsewhere are blunter than any subject's; docs/measurements.md).
  Auto,
  Mean,      ///< every object the mean
  Reference  ///< every object the reference's own template
};

/// Parameters of buildAtlas().
/// How far an atlas continues a bone cut by its reference's field of view, by default (mm).
constexpr double kAtlasExtendCutMm = 30;
/// The template options of an atlas by default: TemplateOptions{} with extendCutMm = kAtlasExtendCutMm.
inline TemplateOptions atlasTemplateOptions() {
  TemplateOptions t;
  t.extendCutMm = kAtlasExtendCutMm;
  return t;
}

struct AtlasOptions {
  std::vector<AtlasObjectSpec> objects;
  AtlasCollisions collisions = AtlasCollisions::Auto;
  /// As `mskseg template` builds them, but bones cut by the reference's field of view are continued beyond it by
  /// extendCutMm (kAtlasExtendCutMm by default): a new subject's scan may show more of them, and a long bone's shaft
  /// goes on much as its last section. Muscles and generic objects are capped at the edge: they taper and end, and
  /// continuing them gained nothing on average (docs/measurements.md).
  TemplateOptions templates = atlasTemplateOptions();
  double marginMm = 30;  ///< the reference image is cropped to the templates' box grown by this, mm, ≥ 0
  std::string modality;  ///< "ct" | "mr"; empty: guessModality() of the image
  /// Further subjects (image, labels: the same labels for the same structures, the same protocol as the reference).
  /// Each is registered to the reference (affine) and each reference template fitted onto its structure there
  /// (fitSurface()): the objects then learn their profiles on every subject and average them, and their templates are
  /// the mean of the subjects' fitted templates laid back onto the reference (`shape`).
  std::vector<std::pair<std::string, std::string>> moreSubjects;
  AtlasShape shape = AtlasShape::Auto;  ///< with moreSubjects: which objects take the subjects' mean shape
  int threads = 0;                      ///< for the registrations, 0 = all cores
};

/// Builds an atlas from a subject's image and labels into the existing, empty folder `dir` (the caller makes the
/// folder appear whole, e.g. by writing into a staging folder). Returns the atlas.json written. Throws IoError naming
/// the file for unreadable inputs, labels on another grid than the image or a label not found; ParameterError for
/// options out of range.
Json buildAtlas(const std::string& imagePath, const std::string& labelsPath, const AtlasOptions& opts,
                const std::string& dir, const ProgressFn& progress = {});

/// An atlas read from its folder.
struct Atlas {
  std::string dir;
  Json meta;             ///< atlas.json
  std::string modality;  ///< "ct" | "mr"
  Scene scene;           ///< scene.json: templates in the reference's world, profiles learned on the reference
  std::shared_ptr<const ImageF> reference;
};

/// Reads an atlas folder: atlas.json of this format and version, every file it lists present with the checksum it
/// records, the scene's objects those of atlas.json. Throws IoError naming the file at fault.
Atlas loadAtlas(const std::string& dir);

/// How an atlas is placed in a subject.
struct PlacementOptions {
  /// Metric of the registrations; unset ("auto"): NCC when the subject's guessed modality is the atlas's, else MI.
  std::optional<RegistrationMetric> metric;
  bool registration = true;              ///< false: the atlas stays where `start` puts it (no registration at all)
  bool perObject = true;                 ///< each object's neighbourhood registered after the global placement
  std::optional<Eigen::Matrix4d> start;  ///< the user's atlas → subject start (RAS); unset: identity + search
  double objectMarginMm = 15;            ///< neighbourhood of an object: its template's box grown by this, mm
  int threads = 0;                       ///< registration threads (0 = all cores)
};

/// One object's placement.
struct ObjectPlacement {
  std::string name;
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();  ///< atlas → subject for this object
  bool registered = false;        ///< its own registration was kept (false: its start placement)
  std::string note;               ///< why its own registration was not kept, if it ran
  bool keptOutOfPartner = false;  ///< its own registration was undone to keep it out of a collision partner
  bool refusedTooFar = false;     ///< its own registration moved it beyond kMaxOwnTurnDegrees / kMaxOwnMoveMm: refused
  std::string carriedBy;          ///< the bone whose placement it started from ("" : the global placement)
  /// Its neighbourhood's metric at its start and at its own placement (NaN where not measured: the global start of
  /// an object that started from its bone's placement).
  double metricBefore = 0, metricAfter = 0;
  double moveDegrees = 0, moveMm = 0;  ///< its own registration against its start placement (at its template centre)
  double seconds = 0;
};

/// A collision pair of the atlas's scene after the placement.
struct PairPlacement {
  std::string a, b;
  /// Share of either template's vertices inside the other (the larger), under the global and the final placement.
  double overlapGlobal = 0, overlapPlaced = 0;
};

/// Where an atlas was placed in a subject.
struct Placement {
  std::string metric;                                    ///< "ncc" | "mi" ("" without registration)
  Eigen::Matrix4d global = Eigen::Matrix4d::Identity();  ///< atlas → subject
  std::optional<RegistrationResult> registration;        ///< the global registration, if it ran
  std::vector<ObjectPlacement> objects;                  ///< per scene object
  std::vector<PairPlacement> pairs;                      ///< per collision pair of the scene
  double seconds = 0;
};

/// Places `atlas` in `subject`: the global registration (affine, from `opts.start` or the moments and a search), then
/// each object's neighbourhood (similarity) from its start: the bones from the global placement, then the other
/// objects; a muscle whose one bone partner kept its own placement starts from that bone's placement (the muscles on a
/// bone turn with it, as a limb turns about its bone: the limb's round outline leaves that turn to the bone and the
/// septa), unless that would push it into a partner. An object's own placement is kept when it improves its
/// neighbourhood's metric and moves it less than 30° and 30 mm from its start; it is then pulled back toward its start
/// as far as needed for no collision pair to reach into each other deeper than at the starts.
Placement placeAtlas(const Atlas& atlas, const ImageF& subject, const PlacementOptions& opts,
                     const ProgressFn& progress = {});

/// The atlas's scene placed in the subject: each template moved by its object's transform (faces flipped if it
/// mirrors), its profiles still learned on the reference where the template came from.
Scene placedScene(const Atlas& atlas, const Placement& placement);

/// An object's own registration is kept only if it moves the object less than these from its start; one that would
/// move it further is refused, and the object is doubtful (judgePlacement()): its own neighbourhood matches the
/// subject best somewhere else than where it starts. On the phantom subjects of docs/measurements.md, the correct runs
/// never come near it; seed 4's hamstrings (Dice 0.89-0.90) would turn 32°, and a thigh turned about its axis by the
/// global registration, each muscle in another's compartment, would turn its hamstrings by 152°.
constexpr double kMaxOwnTurnDegrees = 30.0, kMaxOwnMoveMm = 30.0;

/// Adds the placement's doubts to the objects' quality (segmenter.h) and the case's status: an object whose own
/// registration was refused for moving it beyond kMaxOwnTurnDegrees / kMaxOwnMoveMm is doubtful. (An own turn undone
/// at a collision partner is reported, not judged: on 24 phantom cases such turns of 13-24° came with Dice 0.65-0.97
/// alike; docs/measurements.md.)
void judgePlacement(const Placement& placement, SegmentationResult& result);

/// The subjects an atlas holds: 1 for an atlas of one (format version 1, or built from one subject), else the
/// reference and each further subject.
size_t atlasSubjectCount(const Atlas& atlas);

/// The atlas as subject `k` (0-based; 0 is the reference, the atlas itself) would have made it: that subject's image
/// as the reference, the templates fitted onto that subject as the templates, the profiles still learned on every
/// subject. Its world is that subject's, so `start` (an atlas → image start in the reference's world) becomes
/// start · (reference → subject k)⁻¹, by the registration recorded in atlas.json. Throws Error for k out of range.
Atlas atlasFromSubject(const Atlas& atlas, size_t k);
/// The reference → subject k map of atlas.json (identity for k = 0).
Eigen::Matrix4d atlasReferenceToSubject(const Atlas& atlas, size_t k);

/// Which starts a segmentation with an atlas runs from.
enum class AtlasStarts {
  Reference,  ///< the reference alone, as placed (one run)
  /// Each subject's templates, placed by that subject's image, evolved with the whole scene. An atlas of one subject
  /// starts from its placement, with its muscles on a long bone turned together about that bone
  /// (atlasStartTwists()), and with every object at the global placement (no object's own registration); the run
  /// whose surfaces matched the learned appearance best (the highest sum of the objects' profile matches) is the
  /// result. An atlas of several subjects: each object then starts a final run from the start
  /// whose run matched the learned appearance best there (the highest profile match). A compartment's septa lie at
  /// other angles in other subjects, and no one subject's shape, nor their mean, starts every muscle of every new
  /// subject near enough (docs/measurements.md). Costs one run per start, and with several subjects one more.
  Each
};

/// The step (degrees) between the turned starts of an atlas of one subject, and their number each way.
constexpr double kStartTwistDegrees = 10.0;
constexpr int kStartTwistSteps = 2;

/// The turns (degrees) each subject of `atlas` starts from under `starts`: {0} but for AtlasStarts::Each with an atlas
/// of one subject that has a muscle on a long bone (turnedAboutBone()): 0, then ±k·kStartTwistDegrees for k = 1 ..
/// kStartTwistSteps.
std::vector<double> atlasStartTwists(const Atlas& atlas, AtlasStarts starts);

/// Turns each muscle that lies on exactly one long bone (its one bone collision partner, whose template is at least
/// twice as long as it is wide) by `degrees` about that bone's long axis (the principal axis of its template, through
/// its centroid, in atlas space, directed so that its largest component is positive; right-handed), after the
/// muscle's placement: the muscles on a limb's bone keep their places
/// relative to one another and turn together. Returns the number of muscles turned.
int turnedAboutBone(const Atlas& atlas, Placement& placement, double degrees);

/// One start's run, with AtlasStarts::Each.
struct AtlasStartRun {
  size_t subject = 0;                 ///< 0-based; 0 the reference
  double twistDegrees = 0;            ///< its muscles' turn about their bone (turnedAboutBone())
  bool globalPlacement = false;       ///< every object at the global placement (no object's own registration)
  bool coarseLevelsOnly = false;      ///< its run evolved the coarse levels only (EvolutionOptions::coarseOnly)
  Placement placement;                ///< in the subject's world (atlasFromSubject())
  std::vector<double> profileMatch;   ///< per object, of the run's evolved surface (NaN without the profile force)
  std::vector<QualityStatus> status;  ///< per object (before the output separation where a final run follows)
  std::map<std::string, double> secondsPerStage;  ///< of its segmentation (SegmentationResult::secondsPerStage)
  double seconds = 0;                             ///< placement and segmentation
};

/// A segmentation with an atlas.
struct AtlasSegmentation {
  /// The result's: the kept start's; after a final run, the reference's global placement and each object its start's
  Placement placement;
  Scene scene;                        ///< the placed scene the result evolved
  SegmentationResult result;          ///< the kept start's run, or the final run (judgePlacement() applied)
  std::vector<AtlasStartRun> starts;  ///< each start's run (empty with one start)
  /// per object: the start (index into `starts`) its result comes from (one start for all but after a final run)
  std::vector<size_t> chosen;
};

/// Places `atlas` in `image` and segments it: from the reference alone, or (AtlasStarts::Each) from each start of
/// atlasStartTwists() of each subject and then from each object's best start. Templates a run would remesh are
/// remeshed once, in the atlas's space, before the placement. Several starts evolve their coarse levels only where the
/// run has more than one level (AtlasStartRun::coarseLevelsOnly), and a final run evolves the kept starts whole; with
/// one level each start's run is whole and, for one subject's turned starts, the best is the result. `beforeRun` sees
/// each placed scene before its run, to change it (e.g. a test's refinement flags) or refuse it by throwing (e.g.
/// templates outside the image). Progress runs once over all runs.
AtlasSegmentation segmentWithAtlas(const Atlas& atlas, const ImageF& image, const PlacementOptions& placing,
                                   const SegmentOptions& opts, AtlasStarts starts, const ProgressFn& progress = {},
                                   const std::function<void(Scene&)>& beforeRun = {});

/// The placement as report.json holds it: metric, transforms (4×4 rows), registration stages, per object figures.
Json placementJson(const Placement& placement);

/// The starts of a segmentation with an atlas as report.json holds them: per start its subject (1-based, as atlas.json
/// numbers them), turn, global registration metric, seconds and each object's profile match and status; per object
/// the start its final run started from (1-based, the order of "runs").
Json atlasStartsJson(const AtlasSegmentation& seg, const Scene& scene);

}  // namespace msk
