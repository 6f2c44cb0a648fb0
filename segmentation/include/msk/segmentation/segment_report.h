#pragma once
/// What a run reports (report.json): the settings that produced the result and the figures of the result.
#include "msk/imaging/json.h"
#include "msk/segmentation/scene.h"
#include "msk/segmentation/segmenter.h"

namespace msk {

/// The options and the settings the run resolved from them (preset applied, per-pair collision responses, the
/// axis-first stage's figures), as report.json's "parameters".
Json settingsJson(const SegmentOptions& opts, const SegmentationResult& result);

/// An object's quality figures, status and reasons (report.json's objects[].quality).
Json qualityJson(const ObjectQuality& quality);

/// One object's figures: label, polarity, vertices, time, volumes, template, surface quality, volume model, residual,
/// displacement, levels, time per constraint family and quality (qualityJson()).
Json objectJson(const ObjectResult& object);

/// The run's account for report.json: "status" (the worst object's quality status), "parameters" (settingsJson()),
/// "timing", overlap, the collision pairs with their penetration, the separation, and "objects" (objectJson() each),
/// for `result` of `scene` with `opts`.
Json segmentReport(const SegmentationResult& result, const Scene& scene, const SegmentOptions& opts);

}  // namespace msk
