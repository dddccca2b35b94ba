#pragma once
/// @file AnimateJob.h
/// @brief `animate`: a keyframed spec (deform/AnimSpec.h) run frame by frame on one rest side
///        (DeformRest), each frame equal to `deform` with that frame's spec, byte for byte.
///        Outputs under DIR: frames/deformed.0000.ply ..., vdb/field.0000.vdb (--vdb),
///        preview/frame.0000.png and preview/strip.png (--render), sequence.zip (--zip) and the
///        manifest (job/Sequence.h) with shards and resume.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "job/DeformPipeline.h"
#include "job/Sequence.h"
#include "job/Shard.h"

namespace splatwarp {

struct AnimateJobOptions {
    DeformJobOptions deform;   ///< input, specPath (the keyframed spec), outDir and every deform setting
    int first = 0, last = -1;  ///< frames first..last (inclusive; -1 = the spec's last frame)
    Shard shard;
    bool zip = false;          ///< sequence.zip of the frame PLYs (when this run holds every frame)
    int previewSize = 160;     ///< pixels of a --render preview (square)
    bool warmStart = false;    ///< odd frames' Stage II starts from the frame before's fit (job/WarmStart.h)
};

/// @brief Run this shard's frames; the result counts done, resumed and failed frames.
/// @throws InputError / IoError for a bad model, spec, frame range or unwritable DIR (before any frame).
SequenceResult runAnimateJob(const AnimateJobOptions& options);

/// @brief `animate --specs-only`: write each frame's plain spec to DIR/specs/spec.0000.json ...
///        (what `deform --spec` reads to reproduce that frame); returns how many.
int writeFrameSpecs(const AnimateJobOptions& options);

/// @brief `animate --merge DIR`: mergeManifests(), then the strip and zip when every frame is
///        there (zip: when asked).
nlohmann::json mergeAnimate(const std::string& dir, bool zip);

/// @brief Output file of a frame relative to DIR: "frames/deformed.0007.ply" (kind "deformed"),
///        "vdb/field.0007.vdb", "preview/frame.0007.png", "frames/baseline.0007.ply".
std::string frameFile(const std::string& kind, int frame);

/// @brief Which of `count` frame previews preview/strip.png shows: every one while the strip fits
///        kMaxImageSide (the widest picture our readers take; 102 frames at 160 px), else as many
///        spread evenly over the run, the first and the last included.
std::vector<std::size_t> stripFrames(std::size_t count, int frameWidth);

} // namespace splatwarp
