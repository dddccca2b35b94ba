#include "job/AnimateJob.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <set>

#include "job/DeformSettings.h"
#include "job/WarmStart.h"
#include "job/ZipWriter.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/SafePath.h"
#include "deform/AnimSpec.h"
#include "image/ImageIO.h"
#include "render/Camera.h"
#include "render/RenderDevice.h"
#include "splatwarp/Version.h"

namespace splatwarp {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

/// The frame previews side by side (when every one exists as a regular file), as many as
/// stripFrames() shows.
void writeStrip(const std::string& dir, const json& items)
{
    std::vector<fs::path> previews;
    for (const json& i : items) {
        previews.push_back(fs::path(dir) / frameFile("preview", i.get<int>()));
        std::error_code ec;
        if (!fs::is_regular_file(fs::symlink_status(previews.back(), ec))) return;
    }
    if (previews.empty()) return;
    std::vector<Image> frames{readPng(previews.front().string())};
    const std::vector<std::size_t> shown = stripFrames(previews.size(), frames.front().width);
    for (std::size_t k = 1; k < shown.size(); ++k) frames.push_back(readPng(previews[shown[k]].string()));
    const int w = frames[0].width, h = frames[0].height, c = frames[0].channels;
    Image strip(w * int(frames.size()), h, c);
    for (std::size_t f = 0; f < frames.size(); ++f) {
        if (frames[f].width != w || frames[f].height != h || frames[f].channels != c) return; // not one run's previews
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int k = 0; k < c; ++k) strip.at(int(f) * w + x, y, k) = frames[f].at(x, y, k);
    }
    writePng((fs::path(dir) / "preview" / "strip.png").string(), strip);
}

/// Strip and zip of a run that holds every frame of its range; the zip takes each frame's model
/// at the size its (verified) manifest entry records.
void finishSequence(const std::string& dir, const json& entries, bool zip, bool stage1Only)
{
    json items = json::array();
    for (const json& e : entries) items.push_back(e["frame"]);
    writeStrip(dir, items);
    if (!zip) return;
    std::vector<ZipMember> members;
    for (const json& e : entries) {
        const std::string model = frameFile(stage1Only ? "baseline" : "deformed", e["frame"].get<int>());
        for (const json& f : e["files"])
            if (f["path"] == model) members.push_back({model, f["bytes"].get<std::uint64_t>()});
    }
    writeZip((fs::path(dir) / "sequence.zip").string(), dir, members);
}

} // namespace

std::vector<std::size_t> stripFrames(std::size_t count, int frameWidth)
{
    const std::size_t fit = std::max<std::size_t>(1, std::size_t(kMaxImageSide / std::max(frameWidth, 1)));
    const std::size_t n = std::min(count, fit);
    std::vector<std::size_t> shown(n);
    for (std::size_t k = 0; k < n; ++k) shown[k] = n == 1 ? 0 : k * (count - 1) / (n - 1);
    return shown;
}

namespace {

/// The files frame f may list: its own numbered outputs.
bool isFrameFile(int f, const std::string& rel)
{
    for (const char* kind : {"deformed", "baseline", "vdb", "preview"})
        if (rel == frameFile(kind, f)) return true;
    return false;
}

/// Before any work: the folders animate writes into inside dir are folders of dir itself (a
/// symlink planted there would take the frames elsewhere), and the files it writes last (the
/// strip, the zip) are not refused only after every frame is done.
void checkOutputPlaces(const std::string& dir, bool zip)
{
    checkSubfoldersAreFolders(dir, {"frames", "vdb", "preview", "specs"}, "animate");
    checkOutputPath((fs::path(dir) / "preview" / "strip.png").string());
    if (zip) checkOutputPath((fs::path(dir) / "sequence.zip").string());
}

/// Refuse an input that a run into dir would overwrite (animate writes these paths only).
void checkInputsOutsideOutputs(const DeformJobOptions& o)
{
    for (const std::string& in : {o.input, o.specPath, o.recipePath}) {
        if (in.empty()) continue;
        for (const char* out : {"frames", "vdb", "preview", "specs", "sequence.zip"})
            if (isWithin((fs::path(o.outDir) / out).string(), in))
                throw InputError(msg(in, ": lies in ", (fs::path(o.outDir) / out).string(), ", which animate -o ", o.outDir,
                                     " writes; move it out of the output folder"));
        std::error_code ec;
        const fs::path place = fs::weakly_canonical(fs::absolute(in), ec);
        if (place.parent_path() == fs::weakly_canonical(fs::absolute(o.outDir), ec) &&
            place.filename().string().rfind("manifest", 0) == 0 && place.extension() == ".json")
            throw InputError(msg(in, ": is a manifest of the output folder ", o.outDir, ", which animate rewrites"));
    }
}

/// A frame's manifest entry from its deform report: files, timings, field errors and, with
/// --warm-start, which start it used and why.
json manifestEntry(const FrameReport& report, const json& files)
{
    json entry = {{"files", files}, {"timingsMs", report.toJson()["timingsMs"]}};
    if (report.stage1Errors) entry["fieldError"]["stage1"] = judgeJson(report.stage1Errors->judge);
    const std::optional<StageTwoRecord>& s2 = report.stage2;
    if (s2 && s2->errors) entry["fieldError"]["stage2"] = judgeJson(s2->errors->judge);
    if (s2 && s2->start) {
        entry["start"] = *s2->start;
        if (s2->warmLimit)
            entry["warmStart"] = {{"energy", s2->warmEnergy ? *s2->warmEnergy : s2->fit.energies.at(0).total},
                                  {"limit", *s2->warmLimit}};
    }
    return entry;
}

std::string frameSummary(const json& entry)
{
    if (!entry.contains("fieldError") || !entry["fieldError"].contains("stage2")) return "written";
    const json& e1 = entry["fieldError"]["stage1"];
    const json& e2 = entry["fieldError"]["stage2"];
    char s[160];
    std::snprintf(s, sizeof s, "field error opacity %.4g -> %.4g, color %.4g -> %.4g", e1["opacity"].get<double>(),
                  e2["opacity"].get<double>(), e1["color"].get<double>(), e2["color"].get<double>());
    return s;
}

/// Runs frames through runDeformFrame(), with --warm-start's carried correction: an odd frame
/// (startsWarm) starts Stage II from the frame before's correction, which is the last frame run
/// or, when that was another one (a resumed frame, another shard's, one before --frames), is
/// recomputed first without writing anything; so a frame's bytes equal a one-process run's.
class FrameRunner {
    struct Carried {
        int frame;
        std::optional<StageTwoCorrection> correction; ///< none when Stage II was skipped (rigid) or kept Stage I's model
        double fitEnergy = 0;                         ///< its Stage II's training energy
    };

public:
    FrameRunner(DeformRest& rest, const AnimSpec& anim, const DeformJobOptions& o, bool warmStart)
        : mRest(rest), mAnim(anim), mOptions(o), mWarm(warmStart && !o.stage1Only)
    {
    }
    /// Frame f's report; `written` receives the model written.
    FrameReport run(int f, const FrameOutputs& out, GaussianCloud& written)
    {
        if (!mWarm) return runDeformFrame(mRest, frameSpec(mAnim, f), mOptions, out, &written);
        const std::optional<Carried> previous = startsWarm(f) ? carriedBefore(f) : std::nullopt;
        GaussianCloud stage1;
        StageTwoStart start;
        start.change = [&](const StageOneResult& s1, GaussianCloud& model) {
            if (previous && previous->correction) applyCorrection(*previous->correction, s1.moving, model);
            stage1 = s1.deformed;
        };
        if (previous && previous->correction)
            start.rejects = [&](const StageTwoReport& fit) {
                return !fit.energies.empty() && rejectsWarmStart(fit.energies.front().total, previous->fitEnergy);
            };
        mLast.reset();
        FrameReport report = runDeformFrame(mRest, frameSpec(mAnim, f), mOptions, out, &written, start);
        if (stage1.empty()) { // a rigid frame skips Stage II (start is not called): nothing to carry
            mLast = Carried{f, std::nullopt, 0.0};
            return report;
        }
        StageTwoRecord& s2 = *report.stage2;
        if (!(previous && previous->correction)) s2.start = "cold";
        else s2.warmLimit = kWarmEnergyLimit * previous->fitEnergy;
        // A fit that kept its Stage I model (iteration 0) carries nothing but rounding: its odd frame starts cold.
        // So does one whose split or prune changed the count (a correction is per Gaussian).
        if (s2.fit.bestIteration == 0 || written.size() != stage1.size()) mLast = Carried{f, std::nullopt, 0.0};
        else mLast = Carried{f, stageTwoCorrection(stage1, written), s2.fit.bestEnergy};
        return report;
    }

private:
    /// The frame before f as run by this process, run again (nothing written) when it was not the last.
    std::optional<Carried> carriedBefore(int f)
    {
        if (!mLast || mLast->frame != f - 1) {
            GaussianCloud unused;
            try {
                run(f - 1, FrameOutputs{}, unused);
            } catch (const std::exception& e) {
                throw Error(msg("frame ", f - 1, " (recomputed for the warm start of frame ", f, "): ", e.what()));
            }
        }
        return mLast;
    }

    DeformRest& mRest;
    const AnimSpec& mAnim;
    const DeformJobOptions& mOptions;
    const bool mWarm;
    std::optional<Carried> mLast; ///< the last frame run and its correction
};

} // namespace

std::string frameFile(const std::string& kind, int frame)
{
    char number[16];
    std::snprintf(number, sizeof number, "%04d", frame);
    if (kind == "vdb") return std::string("vdb/field.") + number + ".vdb";
    if (kind == "preview") return std::string("preview/frame.") + number + ".png";
    return "frames/" + kind + "." + number + ".ply";
}

/// The spec's last frame of the run, checked against --frames.
static int lastFrame(const AnimateJobOptions& options, const AnimSpec& anim)
{
    const int last = options.last < 0 ? anim.frames - 1 : options.last;
    if (options.first < 0 || options.first > last || last >= anim.frames)
        throw InputError(msg(anim.source, ": frames ", options.first, "-", last, " are outside 0..", anim.frames - 1));
    return last;
}

int writeFrameSpecs(const AnimateJobOptions& options)
{
    const DeformJobOptions& o = options.deform;
    const AnimSpec anim = parseAnimSpec(readWholeFile(o.specPath, "animation spec"), o.specPath);
    const int last = lastFrame(options, anim);
    checkInputsOutsideOutputs(o);
    checkOutputPlaces(o.outDir, false);
    DirectoryGuard dirs;
    dirs.create((fs::path(o.outDir) / "specs").string());
    for (int f = options.first; f <= last; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "spec.%04d.json", f);
        writeFileAtomic((fs::path(o.outDir) / "specs" / name).string(), frameSpecJson(anim, f).dump(2) + "\n");
    }
    dirs.keep();
    return last - options.first + 1;
}


SequenceResult runAnimateJob(const AnimateJobOptions& options)
{
    const DeformJobOptions& o = options.deform;
    const std::string specText = readWholeFile(o.specPath, "animation spec");
    const AnimSpec anim = parseAnimSpec(specText, o.specPath);
    const int last = lastFrame(options, anim);
    const fs::path dir(o.outDir);
    checkInputsOutsideOutputs(o);
    checkOutputPlaces(o.outDir, options.zip);
    DirectoryGuard dirs; // a run that fails before its first frame leaves no empty folders
    for (const char* sub : {"frames", "vdb", "preview"})
        if (sub == std::string("frames") || (sub == std::string("vdb") && o.writeVdb) || (sub == std::string("preview") && o.render))
            dirs.create((dir / sub).string());

    // All frames share the spec's graph block, so one rest side serves them all.
    std::unique_ptr<DeformRest> rest = prepareDeformRest(o, graphOptionsOf(frameSpec(anim, options.first), o));
    OrbitOptions orbit;
    orbit.views = 1;
    orbit.width = orbit.height = options.previewSize;
    const Camera camera = orbitCameras(rest->model, orbit).front();

    SequenceRun run;
    run.dir = o.outDir;
    run.shard = options.shard;
    run.fileBelongs = isFrameFile;
    for (int f = options.first; f <= last; ++f) run.items.push_back(f);
    json settings = settingsJson(o);
    if (options.warmStart) { // frames in pairs, shards over contiguous ranges of pairs
        settings["warmStart"] = kWarmChain;
        settings["warmLimit"] = kWarmEnergyLimit; // changes which start odd frames use, so their bytes
        const std::vector<int> mine = warmShardFrames(run.items, options.shard);
        run.owns = [mine = std::set<int>(mine.begin(), mine.end())](int f) { return mine.count(f) > 0; };
    }
    FrameRunner frames(*rest, anim, o, options.warmStart);
    // The model's and recipe's contents, not their paths: another model at the same path is
    // recomputed (resume) and refused (merge); ./m.ply and m.ply are one input.
    run.settingsHash = fnv1a64(specText + "\n" + inputsDigest({o.input, o.recipePath}) + "\n" + settings.dump());
    run.header = {{"tool", "splatwarp"}, {"version", SPLATWARP_VERSION_STRING}, {"command", "animate"},
                  {"input", o.input}, {"spec", o.specPath}, {"specHash", fnv1a64(specText)},
                  {"frames", anim.frames}, {"range", {options.first, last}}, {"settings", settings}};
    auto runFrame = [&](int f) {
        FrameOutputs out;
        json files = json::array();
        auto add = [&](std::string& slot, const std::string& kind) {
            slot = (dir / frameFile(kind, f)).string();
            files.push_back(frameFile(kind, f));
        };
        if (o.stage1Only) add(out.baseline, "baseline");
        else add(out.deformed, "deformed");
        if (o.writeVdb && !o.stage1Only) add(out.vdb, "vdb");
        GaussianCloud frame;
        const FrameReport report = frames.run(f, out, frame);
        if (o.render) {
            std::string png;
            add(png, "preview");
            RenderOptions render;
            render.device = rest->device;
            writePng(png, renderGaussiansOn(frame, camera, render));
        }
        return manifestEntry(report, files);
    };
    SequenceResult result = runSequence(run, runFrame, frameSummary);
    dirs.keep();
    if (options.shard.whole() && result.failed == 0) {
        json mine = json::array();
        for (const json& e : result.entries)
            if (e["frame"] >= options.first && e["frame"] <= last) mine.push_back(e);
        finishSequence(o.outDir, mine, options.zip, o.stage1Only);
    }
    return result;
}

json mergeAnimate(const std::string& dir, bool zip)
{
    checkOutputPlaces(dir, zip);
    json merged = mergeManifests(dir, isFrameFile);
    const json settings = merged.value("settings", json::object());
    if (merged["missing"].empty() && merged["failed"].empty())
        finishSequence(dir, merged["entries"], zip, settings.is_object() && settings.contains("stage1Only") && settings["stage1Only"] == true);
    return merged;
}

} // namespace splatwarp
