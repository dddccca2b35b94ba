#include "vdb/SampleGrid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <nanovdb/util/OpenToNanoVDB.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tree/LeafManager.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "vdb/SampleGridImpl.h"
#include "vdb/VdbLibrary.h"
#include "core/Error.h"
#include "core/ParallelFor.h"
#include "core/Memory.h"
#include "core/Progress.h"
#include "field/FeatureDevice.h"
#include "field/FeatureField.h"
#include "field/PreparedGaussian.h"
#include "stage2/BlockFeatures.h"

namespace splatwarp {

namespace {

/// Gaussians per task in the parallel loops (small enough to balance, large enough to amortise).
constexpr std::size_t kGrain = 1024;

/// World-space box of a prepared Gaussian: its pruning AABB (the exact cutoff ellipsoid box,
/// slightly padded; the centre alone when it never contributes), the same box the feature
/// evaluation prunes with, so no contributing pair falls outside the active cells.
void gaussianBox(const PreparedGaussian& g, Vec3d& lo, Vec3d& hi)
{
    const Vec3d c(g.mean);
    const Vec3d half(std::max(g.halfExtent.x, 0.0f), std::max(g.halfExtent.y, 0.0f), std::max(g.halfExtent.z, 0.0f));
    lo = c - half;
    hi = c + half;
}

/// Per-thread union of the cells overlapped by each Gaussian's box (tbb::parallel_reduce body).
struct TopologyOp {
    const std::vector<PreparedGaussian>& gaussians;
    const SampleGrid::Impl& grid;
    openvdb::MaskTree::Ptr tree = std::make_shared<openvdb::MaskTree>();

    TopologyOp(const std::vector<PreparedGaussian>& g, const SampleGrid::Impl& im) : gaussians(g), grid(im) {}
    TopologyOp(TopologyOp& o, tbb::split) : gaussians(o.gaussians), grid(o.grid) {}

    void operator()(const tbb::blocked_range<std::size_t>& r)
    {
        openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(*tree);
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            Vec3d lo, hi;
            gaussianBox(gaussians[i], lo, hi);
            const openvdb::CoordBBox box(grid.cellOf(lo), grid.cellOf(hi));
            // Large boxes (big Gaussians) are filled as tiles where possible; small ones voxel by voxel.
            if (box.volume() > 512) {
                tree->sparseFill(box, true, true);
                continue;
            }
            for (int x = box.min().x(); x <= box.max().x(); ++x)
                for (int y = box.min().y(); y <= box.max().y(); ++y)
                    for (int z = box.min().z(); z <= box.max().z(); ++z) acc.setValueOn(openvdb::Coord(x, y, z));
        }
    }
    void join(TopologyOp& o) { tree->topologyUnion(*o.tree); }
};

/// Refuse before allocating when `cells` (a lower bound or the exact count) cannot fit the budget.
void checkMemory(const SampleGridOptions& o, int shDegree, double cells, const char* what)
{
    const double perCell = double(sampleGridBytesPerCell(o, shDegree));
    if (o.maxMemoryBytes == 0 || cells * perCell <= double(o.maxMemoryBytes)) return;
    throw InputError(msg("sample grid: ", what, " ", cells, " cells x ", formatBytes(perCell), " = ",
                         formatBytes(cells * perCell), ", more than --max-memory ", formatBytes(double(o.maxMemoryBytes)),
                         "; lower --cells (or raise --cell-size) or --samples-per-cell, or raise --max-memory"));
}

/// Cells of the largest single Gaussian box: every one of them becomes active, so this is a lower
/// bound of the grid, known before the topology (which itself could exhaust memory) is built.
double largestBoxCells(const std::vector<PreparedGaussian>& prepared, double h)
{
    double most = 0.0;
    for (const PreparedGaussian& g : prepared) {
        Vec3d lo, hi;
        gaussianBox(g, lo, hi);
        double v = 1.0;
        for (int k = 0; k < 3; ++k) {
            // OpenVDB coordinates are int32 (and dilation adds one): keep well inside.
            if (!(std::fabs(lo[k] / h) < 1e9 && std::fabs(hi[k] / h) < 1e9))
                throw InputError(msg("sample grid: cell size ", h, " is too small for the model's coordinates (cell "
                                     "index beyond 1e9); raise --cell-size or lower --cells"));
            v *= std::floor(hi[k] / h) - std::floor(lo[k] / h) + 1.0;
        }
        most = std::max(most, v);
    }
    return most;
}

/// The grid's options and model are usable.
void checkGridInputs(const GaussianCloud& cloud, const SampleGridOptions& o)
{
    cloud.checkConsistent();
    if (cloud.empty()) throw InputError("sample grid: the model has no Gaussians");
    if (o.samplesPerAxis != kAutoSamplesPerAxis && (o.samplesPerAxis < 2 || o.samplesPerAxis > 16))
        throw InputError(msg("sample grid: samples per cell axis must be in 2..16 (or auto), got ", o.samplesPerAxis));
    if (!(o.cutoff > 0.0f && o.cutoff < 1.0f)) throw InputError(msg("sample grid: cutoff must be in (0, 1), got ", o.cutoff));
    if (!(o.lambdaLpf >= 0.0f)) throw InputError(msg("sample grid: lambdaLpf must be >= 0, got ", o.lambdaLpf));
    if (!(o.cellSize >= 0.0f) || (o.cellSize <= 0.0f && o.cells < 1))
        throw InputError("sample grid: give a positive cell count or cell size");
}

/// Cell edge h: the explicit cell size, else the largest extent of the unfiltered extent boxes / cells.
double cellEdge(const GaussianCloud& cloud, const SampleGridOptions& o)
{
    if (o.cellSize > 0.0f) return o.cellSize;
    Vec3d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
    Vec3d hi = -lo;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        Vec3d a, b;
        gaussianBox(prepareGaussian(cloud, i, 0.0, o.cutoff), a, b);
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], a[k]);
            hi[k] = std::max(hi[k], b[k]);
        }
    }
    const double extent = std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z));
    if (!(extent > 0.0) || !std::isfinite(extent))
        throw InputError("sample grid: the model has zero extent; give an explicit cell size");
    return extent / o.cells;
}

/// The sample set's lattice: SH degree, n samples per cell axis, cell edge h and spacing h / n.
void setLattice(SampleSet& set, int shDegree, int n, double h)
{
    set.shDegree = shDegree;
    set.samplesPerAxis = n;
    set.cellSize = float(h);
    set.spacing = float(h / n);
}

/// Active cells: every cell a Gaussian's box overlaps, then one cell of 26-neighbour dilation.
/// The memory budget is checked at each stage, before the next one could exhaust it.
openvdb::MaskTree::Ptr activeCells(const SampleGrid::Impl& im, const std::vector<PreparedGaussian>& prepared, double h,
                                   int shDegree)
{
    const SampleGridOptions& o = im.options;
    checkMemory(o, shDegree, largestBoxCells(prepared, h), "the largest Gaussian alone covers");
    TopologyOp topo(prepared, im);
    if (o.threaded)
        tbb::parallel_reduce(tbb::blocked_range<std::size_t>(0, prepared.size(), kGrain), topo);
    else
        topo(tbb::blocked_range<std::size_t>(0, prepared.size()));
    // Tiles still count as their volume here: checked before dilation expands them into voxels.
    checkMemory(o, shDegree, double(topo.tree->activeVoxelCount()), "the Gaussians cover at least");
    openvdb::tools::dilateActiveValues(*topo.tree, 1, openvdb::tools::NN_FACE_EDGE_VERTEX, openvdb::tools::EXPAND_TILES,
                                       o.threaded);
    topo.tree->voxelizeActiveTiles(o.threaded);
    return topo.tree;
}

/// The index grid of the active cells (-1 background, cells numbered in leaf order, deterministic
/// for a topology) and each cell's coordinates; returns the cell count.
std::size_t indexCells(SampleGrid::Impl& im, const openvdb::MaskTree& topology, double h, int shDegree)
{
    im.index = openvdb::Int32Grid::create(-1);
    im.index->setTree(std::make_shared<openvdb::Int32Tree>(topology, -1, openvdb::TopologyCopy()));
    im.index->setTransform(openvdb::math::Transform::createLinearTransform(h));
    im.index->transform().postTranslate(openvdb::Vec3d(0.5 * h)); // cell (i,j,k) spans [i h, (i+1) h)
    im.index->setName("cell_index");
    openvdb::tree::LeafManager<openvdb::Int32Tree> leaves(im.index->tree());
    std::vector<std::size_t> leafStart(leaves.leafCount() + 1, 0);
    for (std::size_t l = 0; l < leaves.leafCount(); ++l) leafStart[l + 1] = leafStart[l] + leaves.leaf(l).onVoxelCount();
    const std::size_t cells = leafStart.back();
    const int na = im.options.samplesPerAxis;
    checkMemory(im.options, shDegree, double(cells), "needs");
    if (cells > std::size_t(std::numeric_limits<std::int32_t>::max()) / std::size_t(na * na * na))
        throw InputError(msg("sample grid: ", cells, " cells x ", na * na * na, " samples is too many; use fewer cells"));
    im.cellCoords.resize(3 * cells);
    parallelForRange(leaves.leafCount(), kGrain, im.options.threaded, [&](std::size_t b, std::size_t e) {
        for (std::size_t l = b; l < e; ++l) {
            std::int32_t c = std::int32_t(leafStart[l]);
            for (auto it = leaves.leaf(l).beginValueOn(); it; ++it, ++c) {
                it.setValue(c);
                const openvdb::Coord ijk = it.getCoord();
                for (int k = 0; k < 3; ++k) im.cellCoords[3 * c + k] = ijk[k];
            }
        }
    });
    return cells;
}

/// The samples of cell c from sample s on: a cell-centred axis^3 sub-lattice of spacing h / axis;
/// a fine cell (axis = 2n) octant by octant, n^3 each (compact blocks for Stage II).
void placeCellSamples(SampleSet& set, const std::int32_t* ijk, std::int32_t c, int axis, double h, std::size_t s)
{
    const int na = set.samplesPerAxis;
    const int run = na, octants = axis == na ? 1 : 8; // a fine cell: 8 octants of n^3
    const double spacing = h / axis;
    for (int o = 0; o < octants; ++o) {
        const int off[3] = {(o >> 2) * run, ((o >> 1) & 1) * run, (o & 1) * run};
        for (int a = 0; a < run; ++a)
            for (int bb = 0; bb < run; ++bb)
                for (int cc = 0; cc < run; ++cc, ++s) {
                    set.restPositions[3 * s] = float((ijk[0] * axis + off[0] + a + 0.5) * spacing);
                    set.restPositions[3 * s + 1] = float((ijk[1] * axis + off[1] + bb + 0.5) * spacing);
                    set.restPositions[3 * s + 2] = float((ijk[2] * axis + off[2] + cc + 0.5) * spacing);
                    set.sampleCell[s] = c;
                }
    }
}

/// Samples of every cell (SampleSet::firstSampleOf()); warped = rest, gradients identity.
void placeSamples(SampleGrid::Impl& im, double h)
{
    SampleSet& set = im.set;
    const std::size_t cells = im.cellCoords.size() / 3;
    const std::size_t m = set.firstSampleOf(cells);
    set.restPositions.resize(3 * m);
    set.sampleCell.resize(m);
    parallelForRange(cells, kGrain, im.options.threaded, [&](std::size_t b, std::size_t e) {
        for (std::size_t c = b; c < e; ++c)
            placeCellSamples(set, &im.cellCoords[3 * c], std::int32_t(c), set.axisOf(c), h, set.firstSampleOf(c));
    });
    set.warpedPositions = set.restPositions;
    set.cellGradient.assign(9 * cells, 0.0f);
    for (std::size_t c = 0; c < cells; ++c) set.cellGradient[9 * c] = set.cellGradient[9 * c + 4] = set.cellGradient[9 * c + 8] = 1.0f;
}

/// Cells whose Gaussians are small (SampleGridOptions::fineBelow): the median over the Gaussians
/// centred in the cell of their largest scale is below fineBelow x h/n.
std::vector<std::uint8_t> smallCells(const SampleGrid::Impl& im, const GaussianCloud& cloud, double h)
{
    const std::size_t cells = im.cellCoords.size() / 3;
    std::vector<std::size_t> start(cells + 1, 0);
    for (const std::int32_t c : im.gaussianCell) ++start[std::size_t(c) + 1];
    for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    std::vector<float> largest(cloud.size());
    std::vector<std::size_t> at(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        const Vec3f sc = cloud.scale(i);
        largest[at[std::size_t(im.gaussianCell[i])]++] = std::max(sc.x, std::max(sc.y, sc.z));
    }
    const double below = double(im.options.fineBelow) * h / im.options.samplesPerAxis;
    std::vector<std::uint8_t> small(cells, 0);
    for (std::size_t c = 0; c < cells; ++c) {
        if (start[c + 1] == start[c]) continue;
        const auto first = largest.begin() + std::ptrdiff_t(start[c]), last = largest.begin() + std::ptrdiff_t(start[c + 1]);
        const auto mid = first + (last - first) / 2;
        std::nth_element(first, mid, last);
        small[c] = double(*mid) < below ? 1 : 0;
    }
    return small;
}

/// Per-cell resolution (SampleSet::cellAxis, cellFirst) when fine cells are asked for and found;
/// the set stays uniform otherwise (the same samples, bit for bit, as without the option).
void chooseFineCells(SampleGrid::Impl& im, const GaussianCloud& cloud, double h, int shDegree)
{
    const SampleGridOptions& o = im.options;
    if (!(o.fineBelow > 0.0f)) return;
    std::vector<std::uint8_t> fine = smallCells(im, cloud, h);
    const std::size_t cells = fine.size();
    if (o.fineNeighbours) {
        const std::vector<std::uint8_t> small = fine;
        openvdb::Int32Grid::ConstAccessor acc = im.index->getConstAccessor();
        for (std::size_t c = 0; c < cells; ++c) {
            if (!small[c]) continue;
            const std::int32_t* ijk = &im.cellCoords[3 * c];
            for (int d = 0; d < 27; ++d) {
                const std::int32_t k = acc.getValue(openvdb::Coord(ijk[0] + d / 9 - 1, ijk[1] + (d / 3) % 3 - 1, ijk[2] + d % 3 - 1));
                if (k >= 0) fine[std::size_t(k)] = 1;
            }
        }
    }
    const std::size_t count = std::size_t(std::count(fine.begin(), fine.end(), std::uint8_t(1)));
    if (count == 0) return;
    const int na = o.samplesPerAxis;
    checkMemory(o, shDegree, double(cells) + 7.0 * double(count), "with its fine cells needs the equivalent of");
    SampleSet& set = im.set;
    set.cellAxis.resize(cells);
    set.cellFirst.assign(cells + 1, 0);
    for (std::size_t c = 0; c < cells; ++c) {
        set.cellAxis[c] = std::uint8_t(fine[c] ? 2 * na : na);
        set.cellFirst[c + 1] = set.cellFirst[c] + std::uint64_t(set.cellAxis[c]) * set.cellAxis[c] * set.cellAxis[c];
    }
    if (set.cellFirst[cells] > std::uint64_t(std::numeric_limits<std::int32_t>::max()))
        throw InputError(msg("sample grid: ", set.cellFirst[cells], " samples with the fine cells is too many; use fewer cells or no fine cells"));
    im.stats.fineCells = count;
    im.stats.fineSamplesAdded = std::size_t(set.cellFirst[cells]) - cells * std::size_t(na) * na * na;
}

/// The model whose targets under the fine filter lambda (h/2n)^2 equal the per-Gaussian rest
/// filter: the Gaussians of coarse cells widened by lambda ((h/n)^2 - (h/2n)^2) on every axis
/// (an isotropic filter adds its variance to each of the Gaussian's own axes).
GaussianCloud filterWidenedCloud(const SampleGrid::Impl& im, const GaussianCloud& cloud, double coarse, double fine)
{
    GaussianCloud out = cloud;
    const double extra = coarse - fine;
    parallelFor(cloud.size(), kGrain, im.options.threaded, [&](std::size_t i) {
        if (im.set.axisOf(std::size_t(im.gaussianCell[i])) != im.set.samplesPerAxis) return;
        const Vec3d v = clampedVariances(Vec3d(cloud.scale(i)));
        for (int a = 0; a < 3; ++a) out.logScales[3 * i + std::size_t(a)] = float(0.5 * std::log(v[a] + extra));
    });
    return out;
}

/// Cell of each Gaussian's centre (active: its box, which contains the centre, was activated).
void locateGaussians(SampleGrid::Impl& im, const GaussianCloud& cloud)
{
    im.gaussianCell.resize(cloud.size());
    openvdb::Int32Grid::ConstAccessor acc = im.index->getConstAccessor();
    for (std::size_t i = 0; i < cloud.size(); ++i) im.gaussianCell[i] = acc.getValue(im.cellOf(Vec3d(cloud.mean(i))));
}

/// The index grid in NanoVDB (no statistics or checksum: rebuilt per use and only looked up).
CellIndexGrid nanoIndex(const openvdb::Int32Grid& index)
{
    const nanovdb::GridHandle<nanovdb::HostBuffer> handle =
        nanovdb::openToNanoVDB<nanovdb::HostBuffer>(index, nanovdb::StatsMode::Disable, nanovdb::ChecksumMode::Disable);
    CellIndexGrid out;
    out.assign(handle.data(), handle.size());
    return out;
}

/// Rest targets F, O of every sample with the rest isotropic filter, on options.device: the
/// registered CUDA evaluation (cell lists in the NanoVDB index grid) or the CPU block evaluation.
void evaluateTargets(SampleGrid::Impl& im, const GaussianCloud& cloud, double filterVariance)
{
    SampleSet& set = im.set;
    FeatureOptions& fo = im.targetOptions;
    fo.cutoff = im.options.cutoff;
    fo.filterVariance = float(filterVariance);
    fo.threaded = im.options.threaded;
    fo.device = im.options.device;
    const std::size_t m = set.sampleCell.size();
    FeatureOptions cpu = fo; // its pair lists get what the budget leaves beside the grid (checkMemory())
    if (im.options.maxMemoryBytes) {
        const double n3 = std::pow(double(im.options.samplesPerAxis), 3.0); // fine cells count as their samples
        const double grid = double(m) / n3 * double(sampleGridBytesPerCell(im.options, cloud.shDegree));
        cpu.maxListBytes = std::size_t(std::max(1.0, double(im.options.maxMemoryBytes) - grid));
    }
    set.targetF.assign(m * std::size_t(set.featureStride()), 0.0f);
    set.targetO.assign(m, 0.0f);
    const SampleTargetsFunction cuda = sampleTargetsCuda();
    const FeatureStats fs = runOnDevice(
        fo.device, "sample grid rest targets", cuda != nullptr,
        [&] {
            // The same prepared Gaussians as the CPU path's evaluateFeatures (filter rounded to float).
            const std::vector<PreparedGaussian> g = prepareCloud(cloud, double(fo.filterVariance), fo.cutoff, fo.threaded);
            const CellIndexGrid index = nanoIndex(*im.index);
            SampleTargetsProblem p;
            p.cloud = preparedView(g, cloud, fo.cutoff);
            p.index = &index;
            p.cellSize = double(set.cellSize);
            p.positions = set.restPositions.data();
            p.sampleCell = set.sampleCell.data();
            p.samples = m;
            p.cells = im.cellCoords.size() / 3;
            FeatureStats s;
            cuda(p, set.targetF.data(), set.targetO.data(), &s);
            return s;
        },
        [&] {
            // A cell's n^3 samples are consecutive: one block each (stage2/BlockFeatures.h).
            return evaluateBlockFeatures(cloud, set.restPositions.data(), set.sampleCell.data(), m, cpu, set.targetF.data(),
                                         set.targetO.data());
        },
        &im.stats.device);
    im.stats.pairsTested = fs.pairsTested;
    im.stats.pairsContributing = fs.pairsContributing;
}

} // namespace

std::size_t sampleGridBytesPerCell(const SampleGridOptions& o, int shDegree)
{
    const std::size_t perCell = std::size_t(o.samplesPerAxis) * o.samplesPerAxis * o.samplesPerAxis;
    const std::size_t perSample = SampleSet::bytesPerSample(shDegree) + o.extraBytesPerSample;
    return perCell * perSample + 12 + 36 + 1 + 8; // a cell: coords, gradient, skip, index voxel
}

openvdb::Coord SampleGrid::Impl::cellOf(const Vec3d& p) const
{
    return openvdb::Coord(cellCoordOf(p.x), cellCoordOf(p.y), cellCoordOf(p.z));
}

namespace {

/// samplesPerAxis auto (SampleGridOptions): the n chosen, and the kAutoSamplesMin lattice's
/// active cells it was counted on (the grid's own topology when n stays kAutoSamplesMin).
struct AutoSamples {
    int n = kAutoSamplesMin;
    openvdb::MaskTree::Ptr topology;
};

/// The cells of the kAutoSamplesMin lattice, then the densest n within the sample and memory
/// budgets. A finer n's smaller filter only shrinks the Gaussians' boxes, so its grid has at most
/// these cells.
AutoSamples autoSamplesPerAxis(SampleGrid::Impl& im, const GaussianCloud& cloud, double h)
{
    im.options.samplesPerAxis = kAutoSamplesMin;
    setLattice(im.set, cloud.shDegree, kAutoSamplesMin, h);
    const double spacing = h / kAutoSamplesMin;
    const SampleGridOptions& o = im.options;
    AutoSamples a;
    a.topology =
        activeCells(im, prepareCloud(cloud, double(o.lambdaLpf) * spacing * spacing, o.cutoff, o.threaded), h, cloud.shDegree);
    const double cells = double(a.topology->activeVoxelCount());
    for (int m = a.n + 1; m <= kAutoSamplesMax; ++m) {
        SampleGridOptions finer = o;
        finer.samplesPerAxis = m;
        if (cells * m * m * m > double(o.autoSampleBudget)) break;
        if (o.maxMemoryBytes > 0 && cells * double(sampleGridBytesPerCell(finer, cloud.shDegree)) > double(o.maxMemoryBytes)) break;
        a.n = m;
    }
    return a;
}

} // namespace

int SampleGrid::Impl::cellCoordOf(double x) const { return int(std::floor(x / double(set.cellSize))); }

SampleGrid::SampleGrid(const GaussianCloud& cloud, const SampleGridOptions& options) : mImpl(std::make_unique<Impl>())
{
    vdb::initialize();
    checkGridInputs(cloud, options);
    Impl& im = *mImpl;
    im.options = options;
    Stopwatch watch;
    const double h = cellEdge(cloud, options);
    openvdb::MaskTree::Ptr topology; // auto keeping n = kAutoSamplesMin: the one it counted
    if (options.samplesPerAxis == kAutoSamplesPerAxis) {
        AutoSamples a = autoSamplesPerAxis(im, cloud, h);
        im.options.samplesPerAxis = a.n;
        if (a.n == kAutoSamplesMin) topology = std::move(a.topology);
    }
    const int n = im.options.samplesPerAxis;
    setLattice(im.set, cloud.shDegree, n, h);
    const double spacing = h / n;
    const double filterVariance = double(options.lambdaLpf) * spacing * spacing;

    if (!topology) topology = activeCells(im, prepareCloud(cloud, filterVariance, options.cutoff, options.threaded), h, cloud.shDegree);
    im.stats.cells = indexCells(im, *topology, h, cloud.shDegree);
    locateGaussians(im, cloud);
    chooseFineCells(im, cloud, h, cloud.shDegree);
    placeSamples(im, h);
    im.stats.samples = im.set.sampleCell.size();
    im.stats.topologyMs = watch.ms();
    progress(msg("sample grid: ", im.stats.cells, " cells of ", h, " (", n, "^3 samples each",
                 options.samplesPerAxis == kAutoSamplesPerAxis ? " by --samples-per-cell auto" : "", ", ",
                 im.stats.samples, " samples) in ", int(im.stats.topologyMs), " ms"));
    if (!im.set.uniform())
        progress(msg("sample grid: ", im.stats.fineCells, " fine cells (", 2 * n, "^3 samples: ",
                     im.stats.fineSamplesAdded, " samples added)"));

    watch.reset();
    if (im.set.uniform()) {
        evaluateTargets(im, cloud, filterVariance);
    } else {
        const double fine = filterVariance / 4.0;
        evaluateTargets(im, filterWidenedCloud(im, cloud, filterVariance, fine), fine);
        im.targetOptions.filterVariance = float(filterVariance); // the coarse cells' (see targetOptions())
    }
    im.stats.featuresMs = watch.ms();
    im.computeCellSkip();
    progress(msg("sample grid: rest targets on ", deviceName(im.stats.device), " in ", int(im.stats.featuresMs), " ms; ",
                 im.stats.skippedCells, " of ", im.stats.cells, " cells skipped (empty neighbourhood)"));
}

void SampleGrid::Impl::computeCellSkip()
{
    const std::size_t cells = cellCoords.size() / 3;
    const std::size_t stride = std::size_t(set.featureStride());
    std::vector<std::uint8_t> nonZero(cells, 0);
    parallelForRange(cells, kGrain, options.threaded, [&](std::size_t b, std::size_t e) {
        for (std::size_t c = b; c < e; ++c) {
            const std::size_t s0 = set.firstSampleOf(c), s1 = set.firstSampleOf(c + 1);
            bool any = std::any_of(set.targetO.begin() + s0, set.targetO.begin() + s1, [](float v) { return v != 0.0f; });
            any = any || std::any_of(set.targetF.begin() + s0 * stride, set.targetF.begin() + s1 * stride,
                                     [](float v) { return v != 0.0f; });
            nonZero[c] = any ? 1 : 0;
        }
    });
    set.cellSkip.assign(cells, 1);
    parallelForRange(cells, kGrain, options.threaded, [&](std::size_t b, std::size_t e) {
        openvdb::Int32Grid::ConstAccessor acc = index->getConstAccessor();
        for (std::size_t c = b; c < e; ++c) {
            const std::int32_t* ijk = &cellCoords[3 * c];
            for (int dx = -1; dx <= 1 && set.cellSkip[c]; ++dx)
                for (int dy = -1; dy <= 1 && set.cellSkip[c]; ++dy)
                    for (int dz = -1; dz <= 1; ++dz) {
                        const std::int32_t k = acc.getValue(openvdb::Coord(ijk[0] + dx, ijk[1] + dy, ijk[2] + dz));
                        if (k >= 0 && nonZero[std::size_t(k)]) {
                            set.cellSkip[c] = 0;
                            break;
                        }
                    }
        }
    });
    stats.skippedCells = std::size_t(std::count(set.cellSkip.begin(), set.cellSkip.end(), std::uint8_t(1)));
}

SampleGrid::~SampleGrid() = default;
SampleGrid::SampleGrid(SampleGrid&&) noexcept = default;
SampleGrid& SampleGrid::operator=(SampleGrid&&) noexcept = default;

const SampleGridOptions& SampleGrid::options() const { return mImpl->options; }
const SampleGridStats& SampleGrid::stats() const { return mImpl->stats; }
const SampleSet& SampleGrid::samples() const { return mImpl->set; }
SampleSet& SampleGrid::samples() { return mImpl->set; }
const std::vector<std::int32_t>& SampleGrid::gaussianCell() const { return mImpl->gaussianCell; }
const std::vector<std::int32_t>& SampleGrid::cellCoords() const { return mImpl->cellCoords; }

const FeatureOptions& SampleGrid::targetOptions() const { return mImpl->targetOptions; }

CellIndexGrid SampleGrid::nanoIndexGrid() const { return nanoIndex(*mImpl->index); }

} // namespace splatwarp
