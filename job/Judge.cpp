#include "job/Judge.h"

#include <algorithm>
#include <random>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <limits>
#include <mutex>

#include "core/Error.h"
#include "core/Memory.h"
#include "core/Polar.h"
#include "image/Metrics.h"
#include "render/RenderDevice.h"
#include "stage2/BlockFeatures.h"

namespace splatwarp {

// x_cam = C' (R X + t) must equal x_cam = C X for the rest camera C: C'.rotation = C.rotation R^T.
Camera movedCamera(const Camera& restCamera, const RigidMotion& m)
{
    Camera c = restCamera;
    c.rotation = restCamera.rotation * m.rotation.transposed();
    c.translation = restCamera.translation - c.rotation * m.translation;
    return c;
}

std::optional<RigidMotion> rigidMotionOf(const Deformation& d)
{
    const std::vector<Vec3d>& g = d.graph.nodes();
    const EdConstraints& c = d.handles.constraints;
    const std::size_t n = g.size();
    if (n == 0 || c.target.size() != n) return std::nullopt;
    Vec3d cg, ct, lo = g[0], hi = g[0];
    for (std::size_t j = 0; j < n; ++j) {
        if (!c.fixed[j] && !c.hasTarget[j]) return std::nullopt; // a free node: the solver decides it
        cg += g[j] / double(n);
        ct += c.target[j] / double(n);
        for (int k = 0; k < 3; ++k) { lo[k] = std::min(lo[k], g[j][k]); hi[k] = std::max(hi[k], g[j][k]); }
    }
    // Kabsch: the rotation maximising sum (t - ct) . R (g - cg) is the polar rotation of H.
    Mat3d h;
    for (std::size_t j = 0; j < n; ++j)
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) h.m[a][b] += (c.target[j][a] - ct[a]) * (g[j][b] - cg[b]);
    RigidMotion m;
    m.rotation = polarRotation(h);
    m.translation = ct - m.rotation * cg;
    const double extent = std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z));
    for (std::size_t j = 0; j < n; ++j)
        if (length(m.rotation * g[j] + m.translation - c.target[j]) > 1e-9 * std::max(extent, 1e-30)) return std::nullopt;
    return m;
}

nlohmann::json judgeJson(const JudgeReport& r)
{
    nlohmann::json j = fieldErrorJson(r.field);
    if (r.psnr)
        j["imagePsnr"] = {{"db", std::isfinite(r.psnr->db) ? nlohmann::json(r.psnr->db) : nlohmann::json(nullptr)},
                           {"views", r.psnr->views},
                           {"size", r.psnr->size}};
    return j;
}

std::string judgeText(const JudgeReport& report)
{
    const FieldErrorReport& r = report.field;
    char text[512];
    int n = std::snprintf(text, sizeof text,
                          "held-out points: %zu (%zu inside, %zu outside)\n"
                          "opacity error:   %.6g (inside %.6g, outside %.6g)\n"
                          "color error:     %.6g (inside %.6g, outside %.6g)\n",
                          r.points, r.insidePoints, r.outsidePoints, r.opacity, r.opacityInside, r.opacityOutside,
                          r.color, r.colorInside, r.colorOutside);
    std::string out(text, std::size_t(n));
    if (report.psnr) {
        std::snprintf(text, sizeof text, "image PSNR:      %.6g dB (rigid spec: %d views of %dx%d against the rest model)\n",
                      report.psnr->db, report.psnr->views, report.psnr->size, report.psnr->size);
        out += text;
    }
    return out;
}

JudgeRest prepareJudgeRest(const GaussianCloud& rest, const HeldOutOptions& options)
{
    JudgeRest j;
    j.points = drawJudgePoints(rest, options);
    j.unrotated = unrotatedTarget(rest, j.points);
    return j;
}

namespace {

/// Append point j of one draw, with its weight, to a validation side.
void appendPoint(const JudgeRest& from, std::size_t j, float weight, JudgeRest& to)
{
    const std::size_t stride = from.unrotated.features.size() / std::max<std::size_t>(from.unrotated.size(), 1);
    to.points.rest.insert(to.points.rest.end(), &from.points.rest[3 * j], &from.points.rest[3 * j] + 3);
    const double* f = &from.unrotated.features[stride * j];
    to.unrotated.features.insert(to.unrotated.features.end(), f, f + stride);
    to.unrotated.opacity.push_back(from.unrotated.opacity[j]);
    to.unrotated.weight.push_back(weight);
    to.unrotated.sumOpacity += double(weight) * double(from.unrotated.opacity[j]);
    for (std::size_t s = 0; s < stride; ++s) to.unrotated.sumFeatures += double(weight) * std::fabs(f[s]);
}

/// Draws [first, last) of the judge's rule with their rest side, evaluated in one batch (the block
/// engine gives each point the same bits in any batch); starts[d - first] is draw d's first point.
/// The points at rest only: the Judge warps them (48 bytes a point less than a HeldOutPoints').
JudgeRest drawsWithRest(const GaussianCloud& rest, const JudgeRegion& region, const HeldOutOptions& options, int first,
                        int last, std::vector<std::size_t>& starts)
{
    JudgeRest all;
    starts.assign(1, 0);
    for (int d = first; d < last; ++d) {
        HeldOutOptions o = options;
        o.seed = options.seed + std::uint32_t(d);
        const HeldOutPoints draw = drawJudgePoints(region, o);
        all.points.features = draw.features;
        all.points.rest.insert(all.points.rest.end(), draw.rest.begin(), draw.rest.end());
        starts.push_back(all.points.size());
    }
    all.unrotated = unrotatedTarget(rest, all.points);
    return all;
}

} // namespace

int autoValidationDraws(std::size_t gaussians)
{
    const std::size_t d = kValidationWork / std::max<std::size_t>(gaussians, 1);
    return int(std::clamp<std::size_t>(d, kValidationDraws, 2 * kValidationDraws));
}

JudgeRest prepareValidationRest(const GaussianCloud& rest, const HeldOutOptions& options, int draws)
{
    // Draws in batches of about kBatchBytes of rest side (one set-up of the engine a batch, not a
    // draw; SH degree 0 takes all ten at once, degree 3 one at a time).
    constexpr double kBatchBytes = 64.0 * (1 << 20);
    const double drawBytes = double(options.points) * double(rest.shStride()) * (sizeof(float) + sizeof(double));
    const int batch = std::max(1, int(kBatchBytes / std::max(drawBytes, 1.0)));
    JudgeRest out;
    out.unrotated.shDegree = rest.shDegree;
    std::mt19937_64 rng(options.seed ^ 0x9e3779b97f4a7c15ull);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const JudgeRegion region = judgeRegion(rest);
    std::vector<std::size_t> starts;
    for (int first = 0; first < draws; first += batch) {
        const int last = std::min(draws, first + batch);
        const JudgeRest all = drawsWithRest(rest, region, options, first, last, starts);
        if (first == 0) out.points.features = all.points.features;
        for (int d = first; d < last; ++d) {
            const std::size_t begin = starts[std::size_t(d - first)], end = starts[std::size_t(d - first) + 1];
            std::size_t inside = 0;
            for (std::size_t j = begin; j < end; ++j) inside += all.unrotated.opacity[j] > 0.0f;
            const std::size_t outside = end - begin - inside;
            const double perDraw = double(options.points) / double(kValidationDraws);
            const double keepIn = inside ? std::min(1.0, kValidationInside * perDraw / double(inside)) : 1.0;
            const double keepOut = outside ? std::min(1.0, kValidationOutside * perDraw / double(outside)) : 1.0;
            for (std::size_t j = begin; j < end; ++j) {
                const double keep = all.unrotated.opacity[j] > 0.0f ? keepIn : keepOut;
                if (keep < 1.0 && !(unit(rng) < keep)) continue;
                appendPoint(all, j, float(1.0 / keep), out);
            }
        }
    }
    return out;
}

Judge::Judge(const GaussianCloud& restModel, const JudgeRest& rest, const Deformation& deformation, bool threaded)
    : mPoints(rest.points)
{
    mRender.device = mPoints.features.device;
    mPoints.warped.resize(mPoints.rest.size()); // the validation's rest side holds X only
    mPoints.rotations.resize(3 * mPoints.rest.size());
    warpHeldOutPoints(mPoints, deformation, threaded);
    mTarget = rotatedTarget(rest.unrotated, mPoints);
    std::vector<float>().swap(mPoints.rotations); // the target's only use: 36 bytes a point less
    if (!mPoints.features.device.cuda())
        mBlocks = std::make_shared<const PointBlocks>(mPoints.warped.data(), mPoints.size(), mPoints.features.threaded);
    const std::optional<RigidMotion> motion = rigidMotionOf(deformation);
    if (!motion) return;
    OrbitOptions orbit;
    orbit.views = kViews;
    orbit.width = orbit.height = kSize;
    for (const Camera& c : orbitCameras(restModel, orbit)) {
        mMovedCameras.push_back(movedCamera(c, *motion));
        mTruth.push_back(renderGaussiansOn(restModel, c, mRender));
    }
}

/// The last models' evaluations, by a hash of each model's contents, within a byte budget.
struct Judge::Memo {
    using Key = std::pair<std::uint64_t, std::uint64_t>;
    std::size_t budget = 0; ///< bytes of features and opacity kept (the newest entry always)
    std::mutex mutex;
    std::deque<std::pair<Key, std::shared_ptr<const Evaluation>>> entries; ///< least recently used first

    static std::size_t bytesOf(const Evaluation& e) { return (e.features.size() + e.opacity.size()) * sizeof(float); }

    /// Two 64-bit hashes (different multipliers) over the count, SH degree and every parameter's bits.
    static Key keyOf(const GaussianCloud& m)
    {
        Key k{0x243f6a8885a308d3ull ^ m.size(), 0x13198a2e03707344ull ^ std::uint64_t(m.shDegree)};
        const auto add = [&](std::uint64_t w) {
            k.first = (k.first ^ w) * 0x9e3779b97f4a7c15ull;
            k.first ^= k.first >> 29;
            k.second = (k.second ^ w) * 0xc2b2ae3d27d4eb4full;
            k.second ^= k.second >> 31;
        };
        for (const std::vector<float>* v : {&m.means, &m.rotations, &m.logScales, &m.opacities, &m.sh}) {
            add(v->size());
            std::size_t i = 0;
            for (; i + 2 <= v->size(); i += 2) {
                std::uint64_t w;
                std::memcpy(&w, v->data() + i, sizeof w);
                add(w);
            }
            if (i < v->size()) {
                std::uint32_t w;
                std::memcpy(&w, v->data() + i, sizeof w);
                add(w);
            }
        }
        return k;
    }

    std::shared_ptr<const Evaluation> find(const Key& key)
    {
        const std::lock_guard<std::mutex> lock(mutex);
        for (auto it = entries.begin(); it != entries.end(); ++it)
            if (it->first == key) {
                auto hit = *it;
                entries.erase(it);
                entries.push_back(hit);
                return hit.second;
            }
        return nullptr;
    }

    void add(const Key& key, std::shared_ptr<const Evaluation> e)
    {
        const std::lock_guard<std::mutex> lock(mutex);
        entries.emplace_back(key, std::move(e));
        std::size_t bytes = 0;
        for (const auto& entry : entries) bytes += bytesOf(*entry.second);
        while (entries.size() > 1 && bytes > budget) {
            bytes -= bytesOf(*entries.front().second);
            entries.pop_front();
        }
    }
};

void Judge::forgetLatest()
{
    if (!mMemo) return;
    const std::lock_guard<std::mutex> lock(mMemo->mutex);
    if (!mMemo->entries.empty()) mMemo->entries.pop_back();
}

void Judge::rememberEvaluations(std::size_t bytes)
{
    mMemo = bytes ? std::make_shared<Memo>() : nullptr;
    if (mMemo) mMemo->budget = bytes;
}

std::shared_ptr<const Judge::Evaluation> Judge::evaluate(const GaussianCloud& deformed) const
{
    Memo::Key key;
    if (mMemo) {
        key = Memo::keyOf(deformed);
        if (std::shared_ptr<const Evaluation> hit = mMemo->find(key)) return hit;
    }
    auto e = std::make_shared<Evaluation>();
    e->features.resize(mPoints.size() * std::size_t(deformed.shStride()));
    e->opacity.resize(mPoints.size());
    if (mBlocks && mBlocks->usable())
        mBlocks->evaluate(deformed, mPoints.features, e->features.data(), e->opacity.data());
    else
        evaluatePointsOn(deformed, mPoints.warped.data(), mPoints.size(), mPoints.features, e->features.data(), e->opacity.data());
    if (mMemo) mMemo->add(key, e);
    return e;
}

void Judge::checkSizes() const
{
    if (mTarget.size() != mPoints.size())
        throw InputError(msg("held-out evaluation: a rest side of ", mTarget.size(), " points for ", mPoints.size(), " points"));
}

FieldPointErrors Judge::pointErrors(const GaussianCloud& deformed) const
{
    checkSizes();
    const std::shared_ptr<const Evaluation> e = evaluate(deformed);
    return fieldPointErrors(mTarget, deformed, e->features.data(), e->opacity.data());
}

FieldErrorReport Judge::fieldError(const GaussianCloud& deformed) const
{
    return fieldErrorOf(mTarget, pointErrors(deformed));
}

std::vector<double> Judge::pointScores(const GaussianCloud& deformed) const
{
    const FieldPointErrors e = pointErrors(deformed);
    const double o = opacityScale(), c = colorScale();
    std::vector<double> scores(e.opacity.size());
    for (std::size_t j = 0; j < scores.size(); ++j) scores[j] = e.opacity[j] * o + e.color[j] * c;
    return scores;
}

double Judge::score(const GaussianCloud& deformed) const
{
    // Summed as it goes (the same bits as pointScores()' sum): no per-point arrays beside
    // Stage II's buffers at its checks.
    checkSizes();
    const std::shared_ptr<const Evaluation> e = evaluate(deformed);
    return fieldPointScoreSum(mTarget, deformed, e->features.data(), e->opacity.data(), opacityScale(), colorScale());
}

JudgeReport Judge::judge(const GaussianCloud& deformed) const
{
    JudgeReport r;
    r.field = fieldError(deformed);
    if (!rigid()) return r;
    // One PSNR over every view's pixels: the mean of the per-view squared errors.
    double mse = 0.0;
    for (std::size_t v = 0; v < mTruth.size(); ++v) {
        const double db = psnr(renderGaussiansOn(deformed, mMovedCameras[v], mRender), mTruth[v]);
        mse += (std::isfinite(db) ? std::pow(10.0, -db / 10.0) : 0.0) / double(mTruth.size());
    }
    r.psnr = ImagePsnr{mse > 0.0 ? -10.0 * std::log10(mse) : std::numeric_limits<double>::infinity(), kViews, kSize};
    return r;
}

/// Peak bytes per held-out point: the judge's and the training lattice's points, and the
/// validation points of every 10 draws (2 per point at the 20 draws of small models). Measured
/// (deform bend, 100k against 1M points): lastchance.splat (SH 0) 278 + 347 B a draw-ten;
/// train-1000 (SH 3, 48 feature floats) 4.64 times that, taken as linear in the floats.
double bytesPerEvalPoint(int featureFloats, bool judge, int draws)
{
    const double grow = 1.0 + (4.64 - 1.0) * double(featureFloats - 3) / 45.0;
    return grow * ((judge ? 278.0 : 0.0) + 347.0 * double(draws) / 10.0);
}

void checkEvalPointMemory(std::size_t points, int featureFloats, bool judge, int draws, std::size_t maxMemoryBytes,
                          const char* flag)
{
    if (maxMemoryBytes == 0) return;
    const double need = double(points) * bytesPerEvalPoint(featureFloats, judge, draws);
    const MemoryRoom room = memoryRoom(maxMemoryBytes);
    if (need <= room.left()) return;
    throw InputError(msg("held-out", draws > 0 ? " and validation" : "", " points: ", flag, " ", points,
                         draws > 0 ? msg(" with ", draws, " validation draws") : std::string(), " need about ",
                         formatBytes(need), ", more than ", room.text(), "; lower ", flag,
                         draws > 0 ? " or --validation-draws" : "", ", or raise --max-memory"));
}

} // namespace splatwarp
