#pragma once
/// @file DeformSettings.h
/// @brief The settings table of a deform run: each setting once, with its flag, value type,
///        help, level (user or expert), how its text is read into DeformJobOptions and what it
///        writes to the settings record. From this one table come the flags of `deform`,
///        `animate` and batch jobs (tools/DeformArgs.h), report.json's "settings" and animate's
///        settings hash (job/AnimateJob.cpp); recipes (job/Recipe.h) name the same flags.
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "job/DeformPipeline.h"

namespace splatwarp {

enum class SettingLevel { User, Expert };

/// @brief One setting.
struct Setting {
    std::string flag;     ///< "--curve-split-max"
    std::string typeName; ///< "FLOAT", "INT", "auto|off", ...; empty: a switch that takes no value
    SettingLevel level = SettingLevel::Expert;
    std::string help;
    /// Reads the flag's text into the options (a switch gets "true").
    /// @throws UsageError saying what the value must be
    std::function<void(DeformJobOptions&, const std::string&)> set;
    /// Its keys in the settings record ("cells": 64, ...): what changes a frame's bytes. Some
    /// write only off their default (so the hash of runs made before they existed holds), some
    /// nothing (speed or memory only, or written by another row).
    std::function<void(const DeformJobOptions&, nlohmann::json&)> write;
    /// The value as the flag takes it, for --help's default ("": none shown).
    std::function<std::string(const DeformJobOptions&)> text;

    bool takesValue() const { return !typeName.empty(); }
};

/// @brief Every setting of a deform run, in --help's order, which is also the order they are
///        applied in (a later row may refine an earlier one: --stall-tolerance after --iterations auto).
const std::vector<Setting>& deformSettings();

/// @brief The row of a flag (other commands that take the flag use its help: one text each).
/// @throws std::logic_error for a flag that is not in the table.
const Setting& deformSetting(const std::string& flag);

/// @brief --device's help: "Where <what>: auto (...), cpu or cuda" (every command with --device).
std::string deviceHelp(const std::string& what);

/// @brief The defaults of a deform run: DeformJobOptions' own, with the sample lattice's auto
///        density (deform's default; to-vdb's is fixed) and the host memory budget.
DeformJobOptions deformDefaults();

/// @brief The settings record: every row's keys (report.json "settings"; animate hashes it).
nlohmann::json settingsJson(const DeformJobOptions& options);

} // namespace splatwarp
