#pragma once
/// @file SharedArgs.h
/// @brief Flags that several commands take, each declared once (their help is the deform settings
///        table's, job/DeformSettings.h): `--device` (every command that
///        computes on a device), `--iterations`, `--max-mean-step` and the coverage flags (every
///        command that runs Stage II).
#include <sstream>
#include <string>

#include "Command.h"
#include "core/Device.h"
#include "job/DeformSettings.h"
#include "stage2/StageTwoOptions.h"

namespace splatwarp::cli {

/// @brief `--device auto|cpu|cuda` (default auto) into `device`; `what` says what runs there
///        ("the rest targets run"). A bad name is a usage error; the command resolves the device
///        once (resolveDevice()) before its work.
inline void addDeviceOption(CLI::App* sub, Device& device, const std::string& what)
{
    device = Device::Auto;
    sub->add_option_function<std::string>(
           "--device", [&device](const std::string& name) { device = parseDevice(name); },
           deviceHelp(what))
        ->default_str("auto")
        ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
}

/// @brief `--iterations N|auto` into the Stage II options (default: theirs). `auto` sets the cap
///        and the stall stop (StageTwoOptions::setAutoIterations()); a `--stall-tolerance` given
///        too keeps its value. Anything but auto or a whole number in [0, 1000000] is a usage error.
inline void addIterationsOption(CLI::App* sub, StageTwoOptions& stageTwo)
{
    sub->add_option_function<std::string>(
           "--iterations",
           [sub, &stageTwo](const std::string& word) {
               long n = 0;
               if (word != "auto" && parseWholeNumber(word, 0, 1000000, n)) {
                   stageTwo.iterations = int(n);
                   stageTwo.scheduleIterations = 0;
                   return;
               }
               const float tolerance = stageTwo.stallTolerance;
               stageTwo.setAutoIterations();
               if (sub->count("--stall-tolerance")) stageTwo.stallTolerance = tolerance;
           },
           deformSetting("--iterations").help)
        ->default_str(std::to_string(stageTwo.iterations))
        ->check(autoOrWholeNumber(0, 1000000, "auto|N"));
}

/// @brief `--max-mean-step` into the Stage II options (default: the options' value).
inline void addMaxMeanStepOption(CLI::App* sub, StageTwoOptions& stageTwo)
{
    sub->add_option("--max-mean-step", stageTwo.maxMeanStep, deformSetting("--max-mean-step").help)
        ->capture_default_str()
        ->check(nonNegative());
}

/// @brief `--coverage-steps` and `--rebuild-every` into the Stage II options (defaults: theirs).
inline void addCoverageOptions(CLI::App* sub, StageTwoOptions& stageTwo)
{
    sub->add_option("--coverage-steps", stageTwo.coverageSteps, deformSetting("--coverage-steps").help)
        ->capture_default_str()
        ->check(inRange(1, 1000));
    sub->add_option("--rebuild-every", stageTwo.rebuildEvery, deformSetting("--rebuild-every").help)
        ->capture_default_str()
        ->check(inRange(0, 1000000));
}

} // namespace splatwarp::cli
