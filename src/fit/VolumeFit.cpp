#include "fit/VolumeFit.h"

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <numeric>

#include "core/Error.h"
#include "core/Progress.h"
#include "field/FeatureField.h"
#include "stage2/Densify.h"
#include "stage2/BlockFeatures.h"
#include "stage2/Rounds.h"

namespace splatwarp {

namespace {

/// nanoflann adaptor over the Gaussian centres.
struct CentreCloud {
    const std::vector<float>& means;
    std::size_t kdtree_get_point_count() const { return means.size() / 3; }
    float kdtree_get_pt(std::size_t i, std::size_t d) const { return means[3 * i + d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const { return false; }
};
using CentreTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CentreCloud>, CentreCloud, 3, std::uint32_t>;

/// Residual |O* - O| of the model at every sample (with the fit's filter).
std::vector<float> opacityResidual(const GaussianCloud& cloud, const SampleSet& samples, const StageTwoOptions& o)
{
    FeatureOptions f;
    f.cutoff = o.cutoff;
    f.filterVariance = o.lowPassFilter ? o.lambdaLpf * samples.spacing * samples.spacing : 0.0f;
    std::vector<float> opacity(samples.sampleCount());
    if (samples.sampleCell.size() == samples.sampleCount()) // a volume's samples come in runs of one cell
        evaluateBlockFeatures(cloud, samples.restPositions.data(), samples.sampleCell.data(), samples.sampleCount(), f,
                              nullptr, opacity.data());
    else
        evaluatePointFeatures(cloud, samples.restPositions.data(), samples.sampleCount(), f, nullptr, opacity.data());
    for (std::size_t j = 0; j < opacity.size(); ++j) opacity[j] = std::fabs(samples.targetO[j] - opacity[j]);
    return opacity;
}

/// Every Gaussian of a from-vdb fit moves and has no rest cell: the arrays Densify keeps in step.
struct AllMoving {
    std::vector<std::uint8_t> moving;
    std::vector<std::int32_t> cells;
    explicit AllMoving(std::size_t n) : moving(n, 1), cells(n, -1) {}
};

} // namespace

std::size_t initialGaussianCount(std::size_t budget, const VolumeFitOptions& o)
{
    if (o.rounds <= 1) return budget;
    return std::max<std::size_t>(1, std::size_t(double(budget) * (1.0 - o.splitReserve)));
}

std::size_t pruneTransparent(GaussianCloud& cloud, float alpha)
{
    AllMoving a(cloud.size()); // one prune: Stage II's (stage2/Densify.h)
    FitState d{cloud, a.moving, a.cells};
    return pruneMovingBelow(d, alpha);
}

namespace {

/// The split of splitLargestResidual() on a fit's state.
std::size_t splitLargestResidual(FitState& d, const SampleSet& samples, const std::vector<float>& residual,
                                 std::size_t count)
{
    const GaussianCloud& cloud = d.cloud;
    if (cloud.empty() || count == 0) return 0;
    CentreCloud centres{cloud.means};
    CentreTree tree(3, centres, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree.buildIndex();
    std::vector<double> mass(cloud.size(), 0.0);
    for (std::size_t j = 0; j < residual.size(); ++j) {
        if (!(residual[j] > 0)) continue;
        std::uint32_t nearest = 0;
        float d2 = 0;
        tree.knnSearch(&samples.restPositions[3 * j], 1, &nearest, &d2);
        mass[nearest] += residual[j];
    }
    std::vector<std::size_t> order(cloud.size());
    std::iota(order.begin(), order.end(), std::size_t(0));
    count = std::min(count, order.size());
    std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(count), order.end(),
                      [&](std::size_t a, std::size_t b) { return mass[a] > mass[b] || (mass[a] == mass[b] && a < b); });
    order.resize(count); // Stage II's split with from-vdb's rule (stage2/Densify.h: shrinkSplit())
    return splitGaussians(d, order, shrinkSplit(0.5f));
}

} // namespace

std::size_t splitLargestResidual(GaussianCloud& cloud, const SampleSet& samples, const std::vector<float>& residual,
                                 std::size_t count)
{
    AllMoving a(cloud.size());
    FitState d{cloud, a.moving, a.cells};
    return splitLargestResidual(d, samples, residual, count);
}

VolumeFitReport fitToSamples(GaussianCloud& cloud, const SampleSet& samples, std::size_t budget, const VolumeFitOptions& o)
{
    if (o.rounds < 1 || o.iterations < 0) throw InputError("volume fit: rounds must be >= 1 and iterations >= 0");
    VolumeFitReport report;
    // Every Gaussian moves; one filter cell for all when the samples have cells (stage2/Rounds.h).
    std::vector<std::uint8_t> moving(cloud.size(), 1);
    std::vector<std::int32_t> cells(cloud.size(), samples.cellCount() > 0 && o.stage2.lowPassFilter ? 0 : -1);
    FitState state{cloud, moving, cells};
    RoundsPlan plan;
    for (int round = 0; round < o.rounds; ++round)
        plan.iterations.push_back(o.iterations / o.rounds + (round < o.iterations % o.rounds ? 1 : 0));
    plan.between = [&](int round) {
        Stopwatch watch;
        report.pruned += pruneMovingBelow(state, o.pruneAlpha);
        if (cloud.size() < budget) {
            const std::size_t room = std::min(budget - cloud.size(), cloud.size());
            report.split += splitLargestResidual(state, samples, opacityResidual(cloud, samples, o.stage2), room);
        }
        report.msSplit += watch.ms();
        progress(msg("round ", round + 1, ": ", cloud.size(), " Gaussians after pruning and splitting"));
    };
    report.rounds = fitRounds(state, samples, o.stage2, plan).rounds;
    return report;
}

} // namespace splatwarp
