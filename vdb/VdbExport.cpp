#include "vdb/VdbExport.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "vdb/SampleGridImpl.h"
#include "vdb/VdbLayout.h"
#include "vdb/VdbLibrary.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Polar.h"
#include "core/Progress.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

/// Transform of the sample lattice: voxel size s, index I centred at (I + 1/2) s.
openvdb::math::Transform::Ptr latticeTransform(double voxel)
{
    openvdb::math::Transform::Ptr t = openvdb::math::Transform::createLinearTransform(voxel);
    t->postTranslate(openvdb::Vec3d(0.5 * voxel));
    return t;
}

template <typename GridT>
typename GridT::Ptr makeGrid(const std::string& name, openvdb::math::Transform::Ptr transform, openvdb::GridClass cls)
{
    typename GridT::Ptr g = GridT::create();
    g->setName(name);
    g->setTransform(transform);
    g->setGridClass(cls);
    return g;
}

/// Lattice coordinate of sample (a,b,c) of a cell: (i n + a, j n + b, k n + c).
openvdb::Coord sampleCoord(const std::int32_t* cell, int n, int a, int b, int c)
{
    return openvdb::Coord(cell[0] * n + a, cell[1] * n + b, cell[2] * n + c);
}

/// Per-thread trees of sample values, merged (tbb::parallel_reduce body over cells).
/// value(s, v) returns whether sample s gets a voxel and sets its value.
template <typename TreeT, typename ValueFn>
struct FillSamplesOp {
    const SampleGrid& grid;
    const ValueFn& value;
    TreeT tree;

    FillSamplesOp(const SampleGrid& g, const ValueFn& f) : grid(g), value(f) {}
    FillSamplesOp(FillSamplesOp& o, tbb::split) : grid(o.grid), value(o.value) {}
    void operator()(const tbb::blocked_range<std::size_t>& r)
    {
        const int n = grid.samples().samplesPerAxis;
        openvdb::tree::ValueAccessor<TreeT> acc(tree);
        typename TreeT::ValueType v;
        for (std::size_t c = r.begin(); c != r.end(); ++c) {
            std::size_t s = c * std::size_t(n * n * n);
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b)
                    for (int cc = 0; cc < n; ++cc, ++s)
                        if (value(s, v)) acc.setValue(sampleCoord(&grid.cellCoords()[3 * c], n, a, b, cc), v);
        }
    }
    void join(FillSamplesOp& o) { tree.merge(o.tree); }
};

/// A grid on the sample lattice filled in parallel (cells are disjoint, so merges never collide).
template <typename GridT, typename ValueFn>
typename GridT::Ptr latticeGrid(const SampleGrid& grid, const std::string& name, openvdb::math::Transform::Ptr transform,
                                openvdb::GridClass cls, bool threaded, const ValueFn& value)
{
    FillSamplesOp<typename GridT::TreeType, ValueFn> op(grid, value);
    const tbb::blocked_range<std::size_t> cells(0, grid.samples().cellCount(), 256);
    if (threaded)
        tbb::parallel_reduce(cells, op);
    else
        op(cells);
    typename GridT::Ptr g = makeGrid<GridT>(name, transform, cls);
    g->setTree(std::make_shared<typename GridT::TreeType>(std::move(op.tree)));
    return g;
}

void addMetadata(openvdb::MetaMap& meta, const SampleGrid& grid, const VdbExportOptions& options)
{
    const SampleSet& set = grid.samples();
    meta.insertMeta("creator", openvdb::StringMetadata("splatwarp"));
    meta.insertMeta("source", openvdb::StringMetadata(options.source));
    meta.insertMeta("sh_degree", openvdb::Int32Metadata(set.shDegree));
    meta.insertMeta("cell_size", openvdb::FloatMetadata(set.cellSize));
    meta.insertMeta("samples_per_axis", openvdb::Int32Metadata(set.samplesPerAxis));
    meta.insertMeta("samples_per_cell", openvdb::Int32Metadata(set.samplesPerAxis * set.samplesPerAxis * set.samplesPerAxis));
    meta.insertMeta("cutoff", openvdb::FloatMetadata(grid.options().cutoff));
    meta.insertMeta("lambda_lpf", openvdb::FloatMetadata(grid.options().lambdaLpf));
    if (!options.spec.empty()) meta.insertMeta("spec", openvdb::StringMetadata(options.spec));
}

/// openvdb::io::File::write neither flushes nor checks its stream, so a full disk or `ulimit -f`
/// left a truncated file reported as written: write the same seekable archive to our own stream.
class CheckedArchive : public openvdb::io::Archive {
public:
    void writeTo(std::ostream& os, const openvdb::GridPtrVec& grids, const openvdb::MetaMap& meta) const
    {
        Archive::write(os, grids, /*seekable=*/true, meta);
    }
};

void writeCheckedVdb(const std::string& path, const std::string& temp, const openvdb::GridPtrVec& grids,
                     const openvdb::MetaMap& meta)
{
    std::ofstream os(temp, std::ios::binary);
    if (!os) throw IoError(msg(path, ": cannot open for writing: ", std::strerror(errno)));
    try {
        CheckedArchive archive;
        archive.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
        archive.writeTo(os, grids, meta);
    } catch (const openvdb::Exception& e) {
        throw IoError(msg(path, ": cannot write the VDB file: ", e.what()));
    }
    os.close();
    if (!os) throw IoError(msg(path, ": write failed (disk full or file size limit?)"));
    settleVdbFileUuid(temp);
}

} // namespace

void writeSampleGridVdb(const std::string& path, const SampleGrid& grid, const VdbExportOptions& options)
{
    vdb::initialize();
    Stopwatch watch;
    const SampleSet& set = grid.samples();
    if (!set.uniform()) // its lattices are uniform: `deform --vdb` builds its own uniform grid
        throw InputError(msg(path, ": a sample grid with fine cells cannot be exported (one lattice per file)"));
    const std::size_t k = std::size_t(shCoeffCount(set.shDegree));
    const std::size_t stride = std::size_t(set.featureStride());
    openvdb::math::Transform::Ptr sampleXf = latticeTransform(set.spacing);
    openvdb::math::Transform::Ptr cellXf = latticeTransform(set.cellSize);

    openvdb::GridPtrVec grids;
    auto density = latticeGrid<openvdb::FloatGrid>(grid, "density", sampleXf, openvdb::GRID_FOG_VOLUME, options.threaded,
                                                  [&](std::size_t s, float& v) { v = set.targetO[s]; return true; });
    auto color = latticeGrid<openvdb::Vec3SGrid>(grid, "color", sampleXf, openvdb::GRID_UNKNOWN, options.threaded, [&](std::size_t s, openvdb::Vec3s& v) {
        const float o = set.targetO[s];
        if (!(o > 0.0f)) return false; // colour is undefined where there is no density
        const float* f = &set.targetF[s * stride];
        for (int ch = 0; ch < 3; ++ch) v[ch] = float(0.5 + kShC0 * f[ch] / o);
        return true;
    });
    grids.push_back(density);
    grids.push_back(color);

    // BoolGrid rather than MaskGrid: pyopenvdb cannot load mask grids.
    auto active = makeGrid<openvdb::BoolGrid>("active", cellXf, openvdb::GRID_UNKNOWN);
    {
        openvdb::BoolGrid::Accessor aa = active->getAccessor();
        const std::vector<std::int32_t>& cells = grid.cellCoords();
        for (std::size_t c = 0; c < set.cellCount(); ++c) aa.setValue(openvdb::Coord(cells[3 * c], cells[3 * c + 1], cells[3 * c + 2]), true);
    }
    grids.push_back(active);

    if (options.shGrids) {
        for (std::size_t kk = 0; kk < k; ++kk) {
            grids.push_back(latticeGrid<openvdb::Vec3SGrid>(grid, "sh_" + std::to_string(kk), sampleXf, openvdb::GRID_UNKNOWN, options.threaded,
                                                           [&](std::size_t s, openvdb::Vec3s& v) {
                                                               const float* f = &set.targetF[s * stride + 3 * kk];
                                                               v = openvdb::Vec3s(f[0], f[1], f[2]);
                                                               return true;
                                                           }));
        }
    }
    if (options.stretch) {
        auto stretch = makeGrid<openvdb::FloatGrid>("stretch", cellXf, openvdb::GRID_UNKNOWN);
        openvdb::FloatGrid::Accessor acc = stretch->getAccessor();
        const std::vector<std::int32_t>& cells = grid.cellCoords();
        for (std::size_t c = 0; c < set.cellCount(); ++c)
            acc.setValue(openvdb::Coord(cells[3 * c], cells[3 * c + 1], cells[3 * c + 2]),
                         float(largestSingularValue(&set.cellGradient[9 * c])));
        grids.push_back(stretch);
    }

    openvdb::MetaMap fileMeta;
    addMetadata(fileMeta, grid, options);
    for (openvdb::GridBase::Ptr& g : grids) {
        addMetadata(*g, grid, options);
        if (g->isType<openvdb::FloatGrid>() || g->isType<openvdb::Vec3SGrid>()) g->setSaveFloatAsHalf(options.half);
    }

    AtomicFile out(path);
    writeCheckedVdb(path, out.tempPath(), grids, fileMeta);
    out.commit();
    progress(msg("wrote ", grids.size(), " grids (", set.sampleCount(), " samples, ", set.cellCount(), " cells) to ", path,
                 " in ", int(watch.ms()), " ms"));
}

} // namespace splatwarp
