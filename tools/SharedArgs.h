#pragma once
/// @file SharedArgs.h
/// @brief Flags that several commands take besides deform's (whose flags are its settings table,
///        job/DeformSettings.h, where their help comes from): `--device` (every command that
///        computes on a device), `--max-memory`, `--max-mean-step` and the coverage flags (from-vdb's
///        Stage II).
#include <string>

#include "Command.h"
#include "core/Device.h"
#include "core/Memory.h"
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

/// @brief `--max-memory SIZE` (8G, 512M, ...) into `bytes`, which starts at defaultMemoryBudget().
inline void addMaxMemoryOption(CLI::App* sub, std::size_t& bytes, const std::string& help)
{
    bytes = defaultMemoryBudget();
    sub->add_option_function<std::string>(
           "--max-memory", [&bytes](const std::string& text) { bytes = parseByteSize(text, "--max-memory"); }, help)
        ->type_name("SIZE");
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
