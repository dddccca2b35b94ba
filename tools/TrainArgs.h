#pragma once
/// @file TrainArgs.h
/// @brief The training flags shared by `train` and `from-mesh` (the 3DGS recipe, train/Trainer.h).
#include <string>

#include "Command.h"
#include "RenderArgs.h"
#include "train/Trainer.h"

namespace splatwarp::cli {

/// @brief A start of `count` Gaussians (the value of `flag`) must fit the cap densification keeps:
///        --random-points 3e8 filled the machine before the first step. @throws UsageError
inline void checkStartWithinCap(const char* flag, std::size_t count, std::size_t maxGaussians)
{
    if (count > maxGaussians)
        throw UsageError(msg(flag, " ", count, " is more than --max-gaussians ", maxGaussians,
                             " (the most Gaussians training holds); lower it or raise --max-gaussians"));
}

struct TrainFlags {
    int iterations = 30000;
    int shDegree = 3;
    std::string background = "0,0,0";
    unsigned seed = 0;
    std::size_t maxGaussians = TrainOptions().maxGaussians;
    int progressEvery = TrainOptions().progressEvery;
    std::string report;

    /// @brief compressedSchedule(iterations) with the flags applied.
    TrainOptions options() const
    {
        TrainOptions o = compressedSchedule(iterations);
        o.shDegree = shDegree;
        o.background = parseColour(background);
        o.seed = seed;
        o.maxGaussians = maxGaussians;
        o.progressEvery = progressEvery;
        return o;
    }
};

inline void addTrainFlags(CLI::App* sub, TrainFlags& f)
{
    sub->add_option("--iterations", f.iterations,
                    "Optimisation steps; 3DGS's 30000-step schedule (densify 500..15000 every 100, opacity reset "
                    "every 3000, one SH band per 1000) is scaled to this count")
        ->capture_default_str()
        ->check(inRange(1, 10000000));
    sub->add_option("--sh-degree", f.shDegree, "Highest SH degree of the result")->capture_default_str()->check(inRange(0, 3));
    sub->add_option("--background", f.background,
                    "Background colour r,g,b (display values 0..1): RGBA pictures are composited over it, renders see it")
        ->capture_default_str();
    sub->add_option("--seed", f.seed, "Seed of view order, initial points and splits")->capture_default_str();
    sub->add_option("--max-gaussians", f.maxGaussians, "Densification stops adding beyond this count")
        ->capture_default_str()
        ->check(positive());
    sub->add_option("--progress-every", f.progressEvery, "A progress line every N steps (0: none)")
        ->capture_default_str()
        ->check(nonNegative());
    sub->add_option("--report", f.report, "Write the run's report (JSON: counts, seconds, held-out PSNR/SSIM per view)");
}

} // namespace splatwarp::cli
