#include "job/DeformSession.h"

#include <filesystem>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"

namespace splatwarp {

namespace {

bool sameGraph(const GraphOptions& a, const GraphOptions& b) { return a.nodes == b.nodes && a.k == b.k && a.seed == b.seed; }

std::string inDir(const std::string& dir, const char* name) { return (std::filesystem::path(dir) / name).string(); }

/// What a deform into dir writes, and the earlier run's results it removes (a pose not refined
/// leaves no deformed.ply of another pose beside its baseline.ply).
struct DeformFiles {
    FrameOutputs out;
    std::vector<std::string> stale;
};

DeformFiles deformFiles(const DeformJobOptions& o, const std::string& dir, bool refined)
{
    DeformFiles f;
    f.out.baseline = inDir(dir, "baseline.ply");
    if (!refined) {
        for (const char* stale : {"deformed.ply", "field.vdb", "compare.png", "stretched.png"}) f.stale.push_back(inDir(dir, stale));
        return f;
    }
    f.out.deformed = inDir(dir, "deformed.ply");
    if (o.writeVdb) f.out.vdb = inDir(dir, "field.vdb");
    if (o.render) {
        f.out.compare = inDir(dir, "compare.png");
        f.out.stretched = inDir(dir, "stretched.png");
    }
    return f;
}

std::vector<std::string> inputsOf(const DeformJobOptions& o) { return {o.input, o.specPath, o.recipePath}; }

} // namespace

void checkDeformOutputs(const DeformJobOptions& o)
{
    const DeformFiles f = deformFiles(o, o.outDir, !o.stage1Only);
    OutputSet probe(inputsOf(o)); // never committed: only its checks are used
    for (const std::string& path : {f.out.baseline, f.out.deformed, f.out.vdb, f.out.compare, f.out.stretched,
                                    inDir(o.outDir, "report.json")})
        if (!path.empty()) checkOutputPath(path), probe.checkNotInput(path);
    for (const std::string& stale : f.stale) probe.removeOnCommit(stale);
}

DeformSession::DeformSession(DeformJobOptions options, const DeformSpec& graphSpec)
    : mOptions(std::move(options)), mGraph(graphOptionsOf(graphSpec, mOptions))
{
    const Stopwatch clock;
    mRest = prepareDeformRest(mOptions, mGraph);
    mRestMs = clock.ms();
}

DeformSession::DeformSession(DeformJobOptions options, const DeformSpec& graphSpec, GaussianCloud model)
    : mOptions(std::move(options)), mGraph(graphOptionsOf(graphSpec, mOptions))
{
    const Stopwatch clock;
    mRest = prepareDeformRest(mOptions, mGraph, std::move(model));
    mRestMs = clock.ms();
}

DeformSession::~DeformSession() = default;

const FrameReport& DeformSession::report() const
{
    if (!mFrame) throw UsageError("report needs a pose first");
    return mFrame->report;
}

void DeformSession::checkGraph(const DeformSpec& spec) const
{
    if (!sameGraph(graphOptionsOf(spec, mOptions), mGraph))
        throw InputError(msg(spec.source.empty() ? std::string("spec") : spec.source,
                             ": its graph block (nodes, k, seed) differs from the one this session was prepared for"));
}

const StageOneResult& DeformSession::pose(const DeformSpec& spec)
{
    checkGraph(spec);
    mFrame.reset();
    mPreviewed.reset();
    mFrame = poseFrame(*mRest, spec, mOptions);
    mLastSolve = mFrame->deformation.transforms;
    return mFrame->stage1;
}

DeformSession::Preview DeformSession::preview(const DeformSpec& spec)
{
    if (mRest->stageOne->device() == Device::Cuda) {
        const StageOneResult& stage1 = pose(spec);
        return {stage1.deformed, stage1.movingCount, mFrame->deformation.report.solver.ms, stage1.timings.updateMs};
    }
    checkGraph(spec);
    mFrame.reset();
    mPreviewed.reset();
    const Stopwatch solveClock;
    const Deformation d = solveDeformation(mRest->graph, mRest->model, spec, mOptions.ed, mLastSolve ? &*mLastSolve : nullptr);
    const double solveMs = solveClock.ms();
    const Stopwatch updateClock;
    if (!mPreviewCloud) mPreviewCloud = withShDegree(mRest->model, 0);
    StageOneOptions stageOne = mOptions.stage1;
    stageOne.device = mRest->device;
    const std::size_t moving = applyStageOnePreview(mRest->model, mRest->rig, mRest->graph, d.transforms, d.nodeMoving,
                                                    stageOne, *mPreviewCloud);
    mLastSolve = d.transforms;
    mPreviewed = spec;
    return {*mPreviewCloud, moving, solveMs, updateClock.ms()};
}

void DeformSession::poseThePreview()
{
    if (!mPreviewed) return;
    const DeformSpec spec = std::move(*mPreviewed);
    pose(spec);
}

const GaussianCloud& DeformSession::refine(const RunControl& control)
{
    poseThePreview();
    if (!mFrame) throw UsageError("refine needs a pose first");
    if (mOptions.stage1Only) throw UsageError("this session was prepared for Stage I only (stage1Only)");
    const RunControlScope scope(control);
    FrameResult frame = *mFrame; // a cancelled refine leaves the pose as it was
    refineFrame(*mRest, mOptions, frame);
    mFrame = std::move(frame);
    return *mFrame->fitted;
}

FrameReport DeformSession::write(const std::string& dir, const std::vector<std::pair<std::string, std::string>>& extraFiles)
{
    poseThePreview();
    if (!mFrame) throw UsageError("write needs a pose first");
    OutputSet outputs(inputsOf(mOptions));
    outputs.createDirectory(dir);
    const DeformFiles files = deformFiles(mOptions, dir, refined());
    for (const std::string& stale : files.stale) outputs.removeOnCommit(stale);
    FrameReport report = writeFrame(*mRest, mOptions, *mFrame, files.out);
    report.timingsMs["total"] += mRestMs; // the rest side included
    writeFileAtomic(inDir(dir, "report.json"), report.toJson().dump(2) + "\n");
    for (const auto& [name, contents] : extraFiles) writeFileAtomic(inDir(dir, name.c_str()), contents);
    outputs.commit();
    return report;
}

} // namespace splatwarp
