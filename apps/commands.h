#pragma once
// The subcommands: each takes its arguments (after the command name) and returns the exit code.
#include <functional>
#include <string>
#include <vector>

#include "cli.h"
#include "msk/core/log.h"
#include "msk/imaging/json.h"
#include "msk/imaging/mesh_io.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/segment_options.h"
#include "msk/segmentation/template_builder.h"
#include "slicer_module.h"

namespace msk::cli {
/// mskseg info FILE: a NIfTI volume's geometry and values, or a mesh file's summary.
int cmdInfo(const std::vector<std::string>& args);
/// mskseg phantom: synthetic thigh MRI with ground truth.
int cmdPhantom(const std::vector<std::string>& args);
/// mskseg eval: metrics between label maps or meshes.
int cmdEval(const std::vector<std::string>& args);
/// mskseg rasterize: closed mesh → label map on an image's grid.
int cmdRasterize(const std::vector<std::string>& args);
/// mskseg convert: mesh formats and spaces.
int cmdConvert(const std::vector<std::string>& args);
/// mskseg template: smooth closed template surface from one label of a label map.
int cmdTemplate(const std::vector<std::string>& args);
/// mskseg scene: a scene (scene.json and templates) from the labels of a label map, mirrored if asked.
int cmdScene(const std::vector<std::string>& args);
/// mskseg atlas: an atlas folder (reference image, templates, scene) from a subject's image and labels.
int cmdAtlas(const std::vector<std::string>& args);
/// mskseg segment: evolve a scene's templates into an image.
int cmdSegment(const std::vector<std::string>& args);
/// mskseg batch: one scene segmented in every case of a cohort folder, each case in a process of its own.
int cmdBatch(const std::vector<std::string>& args);
/// mskseg collect: the summary tables of a cohort whose cases separate `mskseg segment` runs segmented.
int cmdCollect(const std::vector<std::string>& args);
/// mskseg bench: benchmarks printing figures, one subcommand each.
int cmdBench(const std::vector<std::string>& args);

/// How `mskseg segment` writes its results besides the segmentation options.
struct SegmentOutputs {
  MeshSpace space = MeshSpace::LPS;  ///< space of the mesh files (tagged)
  bool qcPictures = true;            ///< write qc/<name>_{axial,coronal,sagittal}.png and qc/mosaic.png
  std::string qcReference;           ///< a label map whose contours the QC pictures show as the reference (optional)
  bool split = false;                ///< also one mask per structure, labels/<name>.nii.gz
  std::string imageExport;           ///< "vti": also image.vti and labels.vti with their world placement
};
/// Binds the options of `mskseg segment` that steer the segmentation (all but --image, --scene and --out) into
/// `opts` and `outputs`; their ranges are checked by checkSegmentOptions() after parsing.
void addSegmentOptions(CLI::App& app, SegmentOptions& opts, SegmentOutputs& outputs);

/// Binds the template options (--vertices, --smooth, --extend-cut) of `template`, `scene` and `atlas` into `opts`;
/// `bonesOnly`: the help says --extend-cut continues bones only (as `atlas` does).
void addTemplateOptions(CLI::App& app, TemplateOptions& opts, bool bonesOnly = false);

/// The 3D Slicer module parameters of those options (--vertices labelled `verticesLabel`, --smooth, --extend-cut with
/// the default `extendCutMm`).
std::vector<SlicerParameter> templateParameters(const std::string& verticesLabel, double extendCutMm);
/// Throws IoError naming `labelsPath` (and the labels it holds) if `labels` has no voxel of `label`.
void requireLabel(const LabelMap& labels, long label, const std::string& labelsPath);

/// `s` with the characters special in HTML and XML (& < > " ') written as character references.
std::string markupEscaped(const std::string& s);

/// The command line as a JSON array ["mskseg", command, args...], for the results it produced.
Json commandLineJson(const std::string& command, const std::vector<std::string>& args);

/// A progress reporter printing "stage: NN%" lines on stderr (throttled), silent under --quiet; with progress tags on
/// (setProgressTags()) also the task's fraction as <filter-progress> tags on stdout, under --quiet too.
ProgressFn stderrProgress(const std::string& task);

/// Turns the <filter-progress> tags of stderrProgress() on (3D Slicer reads them from a module's stdout).
void setProgressTags(bool on);

/// Throws IoError naming `dir` if it cannot become an output folder (it is a file, or a file stands where one of its
/// missing parents would be created): called before long work, so that a mistyped --out fails at once.
void checkOutputFolder(const std::string& dir);

/// The same for an output file: throws IoError naming `path` if it is a folder or its parents cannot be created.
void checkOutputFile(const std::string& path);

/// Creates the missing parent folders of `path`, then runs `write` (which writes `path` atomically); if it throws,
/// the folders created are removed again.
void writeFileWithParents(const std::string& path, const std::function<void()>& write);

/// Writes into a staging folder beside `dir`, then moves the files into `dir` (created with its missing parents); on
/// error the staging folder and the parents created are removed and nothing appears in `dir`.
void writeFolderAtomically(const std::string& dir, const std::function<void(const std::string& staging)>& write);
}  // namespace msk::cli
