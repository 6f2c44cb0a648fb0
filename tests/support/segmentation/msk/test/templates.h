#pragma once
/// Templates for the real-scan tests and benchmarks: a structure's smooth template taken from the other side.
#include "msk/core/triangle_mesh.h"
#include "msk/imaging/volume.h"
#include "msk/segmentation/template_builder.h"

namespace msk::test {

/// Template of the other side: the smooth template of `fromLabel`, mirrored across the sagittal plane x = `midX`
/// (RAS mm).
TriangleMesh mirroredTemplate(const LabelMap& labels, int fromLabel, double midX, const TemplateOptions& opts = {});

}  // namespace msk::test
