// mskseg atlas: an atlas folder from a subject's image and labels (reference image, templates, scene, checksums).
#include <iostream>

#include "commands.h"
#include "msk/segmentation/atlas.h"
#include "slicer_module.h"

namespace msk::cli {

namespace {
/// The module's parameters: the options 3D Slicer's panel shows for `mskseg atlas`.
SlicerModule atlasModule() {
  SlicerModule m;
  m.title = "mskseg atlas";
  m.description =
      "Builds an atlas folder for mskseg segment from a subject's image and its label map: the reference image, a "
      "template surface per structure and the scene.";
  using P = SlicerParameter;
  m.groups.push_back({"Input and output",
                      "The reference subject and the atlas folder written.",
                      false,
                      {P("image", "--image", "Reference volume").type("scalar").extensions(".nii.gz"),
                       P("image", "--labels", "Its label map").type("label").extensions(".nii.gz"),
                       P("string", "--objects", "Structures (NAME:LABEL:KIND,...)"),
                       P("directory", "--out", "Atlas folder to write").output()}});
  SlicerGroup build{
      "Atlas",
      "What the atlas keeps.",
      true,
      {P("string-enumeration", "--collisions", "Collision pairs").byDefault("auto").choices({"auto", "all", "none"}),
       P("string-enumeration", "--modality", "Modality").byDefault("auto").choices({"auto", "ct", "mr"}),
       P("double", "--margin", "Margin kept around the structures (mm)").byDefault("30").range(0, 500, 1)}};
  for (const SlicerParameter& p : templateParameters("Vertices per template", AtlasOptions{}.templates.extendCutMm))
    build.parameters.push_back(p);
  build.parameters.push_back(progressTagsParameter());
  m.groups.push_back(build);
  return m;
}
}  // namespace

int cmdAtlas(const std::vector<std::string>& argv) {
  CommandLine app(
      "atlas",
      "Builds an atlas folder from a subject's image and labels: the reference image (cropped to the objects plus "
      "--margin), one template per object (as `mskseg template` builds it), a scene.json whose objects learn their "
      "intensity profiles on the reference image, and atlas.json (format version, objects with labels, kinds and "
      "colours, the intensity normalisation, checksums of the sources and of every file). `mskseg segment --atlas "
      "DIR` then places it in a new subject by registration.");
  std::vector<std::string> imagePaths, labelsPaths;
  std::string objects, out, collisions = "auto", modality, shape = "auto";
  AtlasOptions opts;
  app.add_option("--image", imagePaths,
                 "a subject's image (NIfTI); repeat with --labels for several subjects of one protocol, the first "
                 "the reference")
      ->required();
  app.add_option("--labels", labelsPaths, "that subject's label map (NIfTI, same grid; the same labels throughout)")
      ->required();
  app.add_option("--shape", shape,
                 "with several subjects, which templates are the subjects' mean shape: auto (bones; muscles and "
                 "generic objects keep the first subject's own, default), mean (all) or reference (none)")
      ->check(CLI::IsMember({"auto", "mean", "reference"}));
  app.add_option("--threads", opts.threads,
                 "threads for the registrations of several subjects (default 0 = all cores)");
  app.add_option("--objects", objects, "NAME:LABEL[:KIND],... (KIND bone|muscle|generic, default generic)")->required();
  app.add_option("--collisions", collisions,
                 "auto (pairs whose templates come within 2 mm, default), all (every pair) or none")
      ->check(CLI::IsMember({"auto", "all", "none"}));
  app.add_option("--modality", modality, "ct, mr or auto (default: guessed from the intensities)")
      ->check(CLI::IsMember({"ct", "mr", "auto"}));
  addNumber(app, "--margin", opts.marginMm, "margin around the objects kept of the image, mm (default 30)");
  addTemplateOptions(app, opts.templates, true);
  app.add_option("--out", out, "the atlas folder to write, created with its parents (appears whole or not at all)")
      ->required();
  addProgressTagsOption(app);
  if (handleSlicerXml(app, argv, atlasModule())) return 0;
  if (!parseArgs(app, argv)) return 0;
  if (imagePaths.size() != labelsPaths.size())
    throw ParameterError("--labels", std::to_string(labelsPaths.size()) + " given",
                         "give one per --image (" + std::to_string(imagePaths.size()) + "), in the same order");
  if (!(opts.threads >= 0 && opts.threads <= 1024))
    throw ParameterError("--threads", std::to_string(opts.threads), "must be in [0, 1024]");
  for (size_t k = 1; k < imagePaths.size(); ++k) opts.moreSubjects.emplace_back(imagePaths[k], labelsPaths[k]);
  opts.shape = shape == "mean" ? AtlasShape::Mean : shape == "reference" ? AtlasShape::Reference : AtlasShape::Auto;
  opts.objects = parseAtlasObjects(objects);
  opts.collisions = collisions == "all"    ? AtlasCollisions::All
                    : collisions == "none" ? AtlasCollisions::None
                                           : AtlasCollisions::Auto;
  opts.modality = modality == "auto" ? "" : modality;
  checkTemplateOptions(opts.templates);
  checkOutputFolder(out);
  Json atlas;
  writeFolderAtomically(out, [&](const std::string& dir) {
    atlas = buildAtlas(imagePaths[0], labelsPaths[0], opts, dir, stderrProgress("atlas"));
  });
  std::cout << "atlas of " << opts.objects.size() << " object(s) from " << imagePaths.size() << " subject(s) -> " << out
            << " (modality " << atlas["modality"].get<std::string>() << ", reference " << atlas["reference"]["dims"][0]
            << "x" << atlas["reference"]["dims"][1] << "x" << atlas["reference"]["dims"][2] << " voxels)\n";
  for (const Json& o : atlas["objects"]) {
    std::cout << "  " << o["name"].get<std::string>() << " (label " << o["label"] << ", "
              << o["kind"].get<std::string>() << "): template " << o["template_vertices"] << " vertices, "
              << o["template_volume_ml"].get<double>() << " mL";
    if (!o["cut_by_field_of_view"].empty()) {
      std::cout << ", cut by the field of view (";
      for (size_t f = 0; f < o["cut_by_field_of_view"].size(); ++f)
        std::cout << (f ? ", " : "") << o["cut_by_field_of_view"][f].get<std::string>();
      std::cout << ") and continued " << o["extended_mm"].get<double>() << " mm beyond it";
    }
    if (o.contains("subjects"))
      for (const Json& f : o["subjects"])
        if (f.contains("fit_mean_mm"))
          std::cout << "; fitted onto subject " << f["subject"] << " to " << f["fit_mean_mm"].get<double>()
                    << " mm (mean), volume ratio " << f["fit_volume_ratio"].get<double>();
    std::cout << "\n";
  }
  return 0;
}

}  // namespace msk::cli
