/// Reading fog volumes (vdb/Volume.h): grid choice, input checks, trilinear lookups, samples.
#include "vdb/Volume.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <unistd.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Count.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/Morphology.h>

#include "vdb/VdbLayout.h"
#include "vdb/VdbLibrary.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Memory.h"
#include "core/ParallelFor.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

struct Volume::Impl {
    VolumeInfo info;
    openvdb::FloatGrid::Ptr density;
    std::vector<openvdb::Vec3SGrid::Ptr> features; ///< F_k grids; empty: F = O * constantSh (colour white)
    float constantSh = float(0.5 / kShC0);         ///< f_dc of white (RGB 1)
};

namespace {

/// The SH degrees splatwarp writes and fits (3DGS's 0..3).
constexpr int kMaxShDegree = 3;

std::uint64_t availableMemory()
{
    std::ifstream in("/proc/meminfo");
    std::string key;
    std::uint64_t kb = 0;
    std::string unit;
    while (in >> key >> kb >> unit)
        if (key == "MemAvailable:") return kb * 1024;
    return std::uint64_t(sysconf(_SC_PHYS_PAGES)) * std::uint64_t(sysconf(_SC_PAGE_SIZE));
}

void checkMemory(const std::string& where, std::uint64_t voxels, const VolumeReadOptions& o)
{
    const std::uint64_t limit = o.memoryLimit > 0 ? o.memoryLimit : availableMemory();
    const double need = double(voxels) * double(o.bytesPerVoxel);
    if (need > double(limit))
        throw InputError(msg(where, ": ", voxels, " active voxels need at least ", formatBytes(need), " to fit (",
                             o.bytesPerVoxel, " B each), more than ",
                             o.memoryLimit > 0 ? msg("--max-memory ", formatBytes(double(limit)),
                                                     " (fewer samples per voxel need less)")
                                               : msg("the ", formatBytes(double(limit)), " available")));
}

std::string gridList(const openvdb::GridPtrVec& grids)
{
    std::string s;
    for (const auto& g : grids) s += (s.empty() ? "" : ", ") + printableLine(g->getName()) + " (" + g->valueType() + ")";
    return s.empty() ? "none" : s;
}

openvdb::GridBase::ConstPtr findGrid(const openvdb::GridPtrVec& grids, const std::string& name)
{
    for (const auto& g : grids)
        if (g->getName() == name) return g;
    return nullptr;
}

/// OpenVDB reads the first of several grids of a name (after a warning): which one was meant is
/// not ours to guess.
void checkUniqueName(const std::string& path, const openvdb::GridPtrVec& grids, const std::string& name)
{
    const auto count = std::count_if(grids.begin(), grids.end(), [&](const auto& g) { return g->getName() == name; });
    if (count > 1)
        throw InputError(msg(path, ": ", count, " grids are named '", printableLine(name),
                             "' (OpenVDB would read the first); rename all but one"));
}

/// The density grid's name: the requested one, else `density`, else the only FloatGrid.
std::string chooseDensityGrid(const std::string& path, const openvdb::GridPtrVec& grids, const std::string& wanted)
{
    auto isFloat = [](const openvdb::GridBase::ConstPtr& g) { return g && g->isType<openvdb::FloatGrid>(); };
    if (!wanted.empty()) {
        if (!isFloat(findGrid(grids, wanted)))
            throw InputError(msg(path, ": no FloatGrid named '", printableLine(wanted), "'; grids: ", gridList(grids)));
        return wanted;
    }
    if (isFloat(findGrid(grids, "density"))) return "density";
    std::vector<std::string> floats;
    for (const auto& g : grids)
        if (isFloat(g)) floats.push_back(g->getName());
    if (floats.size() == 1) return floats[0];
    throw InputError(msg(path, floats.empty() ? ": no float grid" : ": several float grids and none named 'density'",
                         " (choose one with --grid); grids: ", gridList(grids)));
}

/// The largest |value| read: the fit squares values and sums the squares over up to ~1e9 samples
/// in float32 (3e38 gave only "the energy at the start is not finite").
constexpr double kMaxAbsValue = 1e12;
/// Voxel sizes the float32 fit can work with: the Gaussians' log-scales, volumes (size^3) and
/// energies stay finite (1e-200 gave NaN, 1e30 a model no writer takes).
constexpr double kMinVoxelSize = 1e-6, kMaxVoxelSize = 1e6;
/// Active voxels' world positions, in voxels: float32 still resolves an eighth of a voxel there
/// (1e8 voxels from the origin, the training samples of a voxel collapsed onto one point).
constexpr double kMaxVoxelsFromOrigin = double(1 << 20);
/// The largest low-pass filter strength of our own files' metadata: a 10-voxel standard deviation.
constexpr float kMaxLambdaLpf = 100.0f;

template <typename T>
bool inRange(const T& v)
{
    if constexpr (std::is_same_v<T, float>) return std::fabs(double(v)) <= kMaxAbsValue; // false for NaN
    else return inRange(v[0]) && inRange(v[1]) && inRange(v[2]);
}

/// Refuse NaN/Inf or overflowing values: every voxel and tile, active or not (trilinear sampling
/// in the band reads inactive ones), and the background.
template <typename GridT>
void checkFinite(const std::string& path, const GridT& grid)
{
    const std::string which = msg(path, ": grid '", printableLine(grid.getName()), "'");
    if (!inRange(grid.background()))
        throw InputError(msg(which, " has background ", grid.background(), " (finite, |value| <= ", kMaxAbsValue, ")"));
    std::size_t bad = 0;
    openvdb::Coord first;
    for (auto it = grid.cbeginValueAll(); it; ++it)
        if (!inRange(*it) && bad++ == 0) first = it.getCoord();
    if (bad > 0)
        throw InputError(msg(which, " has ", bad, " NaN/Inf values or values beyond +-", kMaxAbsValue,
                             " (first at voxel ", first, ")"));
}

/// The voxel size, and the active voxels' world positions, usable in float32 (see the limits).
void checkWorldScale(const std::string& where, const openvdb::FloatGrid& density)
{
    const double voxel = density.transform().voxelSize()[0];
    if (!(voxel >= kMinVoxelSize && voxel <= kMaxVoxelSize))
        throw InputError(msg(where, ": voxel size ", voxel, " (the float32 fit needs ", kMinVoxelSize, " to ",
                             kMaxVoxelSize, " world units)"));
    const openvdb::CoordBBox box = density.evalActiveVoxelBoundingBox();
    for (int corner = 0; corner < 8; ++corner) {
        const openvdb::Coord c((corner & 1 ? box.max() : box.min()).x(), (corner & 2 ? box.max() : box.min()).y(),
                               (corner & 4 ? box.max() : box.min()).z());
        const openvdb::Vec3d p = density.indexToWorld(c);
        for (int a = 0; a < 3; ++a)
            if (!(std::fabs(p[a]) <= kMaxVoxelsFromOrigin * voxel))
                throw InputError(msg(where, ": active voxel ", c, " lies at world ", p, ", more than ",
                                     kMaxVoxelsFromOrigin, " voxels from the origin (float32 positions there do "
                                     "not resolve a voxel's samples)"));
    }
}

template <typename T>
T metaOr(const openvdb::MetaMap& m, const std::string& key, T fallback)
{
    using MetaT = openvdb::TypedMetadata<T>;
    auto v = m.getMetadata<MetaT>(key);
    return v ? v->value() : fallback;
}

void openFile(openvdb::io::File& file, const std::string& path)
{
    try {
        // No delayed loading: it trusts the file's `file_delayed_load` masks and sizes, and a corrupt
        // one failed an assertion in OpenVDB (exit 134) instead of an error.
        file.open(/*delayLoad=*/false);
    } catch (const std::exception& e) {
        throw InputError(msg(path, ": not an OpenVDB file (", e.what(), ")"));
    }
}

/// A grid's data; a cut or corrupt file is an InputError naming it (OpenVDB says "KeyError: Map
/// is not registered" for a file cut inside a transform, std::ios errors for others).
openvdb::GridBase::Ptr readGrid(openvdb::io::File& file, const std::string& path, const std::string& name)
{
    try {
        return file.readGrid(name);
    } catch (const std::exception& e) {
        throw InputError(msg(path, ": grid '", printableLine(name), "' cannot be read (truncated or corrupt file?): ", e.what()));
    }
}

/// Our own sh_<k> grids, or a colour grid turned into F_dc = O (c - 1/2) / C0.
void readFeatures(openvdb::io::File& file, const openvdb::GridPtrVec& grids, const VolumeReadOptions& o,
                  Volume::Impl& v)
{
    VolumeInfo& info = v.info;
    if (info.ownFile && findGrid(grids, "sh_0")) {
        // Our own metadata is input like any other: a forged degree must not size the features.
        const int degree = metaOr<std::int32_t>(*file.getMetadata(), "sh_degree", 0);
        if (degree < 0 || degree > kMaxShDegree)
            throw InputError(msg(info.path, ": metadata sh_degree is ", degree, " (an SH degree: 0 to ", kMaxShDegree, ")"));
        for (int k = 0; k < shCoeffCount(degree); ++k) {
            const auto base = findGrid(grids, "sh_" + std::to_string(k));
            if (!base || !base->isType<openvdb::Vec3SGrid>())
                throw InputError(msg(info.path, ": sh_degree ", degree, " but no Vec3S grid sh_", k));
            auto g = openvdb::gridPtrCast<openvdb::Vec3SGrid>(readGrid(file, info.path, "sh_" + std::to_string(k)));
            if (!g) throw InputError(msg(info.path, ": sh_degree ", degree, " but no Vec3S grid sh_", k));
            if (g->transform() != v.density->transform())
                throw InputError(msg(info.path, ": grid sh_", k, " has another transform than '", printableLine(info.grid), "'"));
            checkFinite(info.path, *g);
            v.features.push_back(g);
        }
        info.shDegree = degree;
        info.colorGrid = "sh_*";
        return;
    }
    std::string name = o.colorGrid;
    if (name.empty()) name = findGrid(grids, "color") ? "color" : (findGrid(grids, "Cd") ? "Cd" : "");
    if (name.empty() || name == "none") {
        info.notes.push_back("no colour grid: white");
        return;
    }
    checkUniqueName(info.path, grids, name);
    auto base = findGrid(grids, name);
    if (!base || !base->isType<openvdb::Vec3SGrid>())
        throw InputError(msg(info.path, ": no Vec3S colour grid named '", printableLine(name), "'; grids: ", gridList(grids)));
    auto color = openvdb::gridPtrCast<openvdb::Vec3SGrid>(readGrid(file, info.path, name));
    checkFinite(info.path, *color);
    if (color->transform() != v.density->transform())
        throw InputError(msg(info.path, ": colour grid '", printableLine(name), "' has another transform than '", printableLine(info.grid), "'"));
    auto f = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    f->setTransform(v.density->transform().copy());
    auto fa = f->getAccessor();
    auto ca = color->getConstAccessor();
    for (auto it = v.density->cbeginValueOn(); it; ++it) {
        const openvdb::Vec3s c = ca.isValueOn(it.getCoord()) ? ca.getValue(it.getCoord()) : openvdb::Vec3s(1.0f);
        const openvdb::Vec3s sh = (c - openvdb::Vec3s(0.5f)) * float(*it / kShC0);
        if (!inRange(sh)) // each factor in range, their product overflowing
            throw InputError(msg(info.path, ": colour grid '", printableLine(name), "' at voxel ", it.getCoord(), ": colour ",
                                 c, " times density ", *it, " is beyond +-", kMaxAbsValue));
        fa.setValue(it.getCoord(), sh);
    }
    v.features.push_back(f);
    info.colorGrid = name;
}

} // namespace

Volume readVolume(const std::string& path, const VolumeReadOptions& o)
{
    vdb::initialize();
    checkVdbFileLayout(path); // before OpenVDB, which reads garbage sizes from a cut file
    openvdb::io::File file(path);
    openFile(file, path);
    openvdb::GridPtrVec grids;
    try {
        grids = *file.readAllGridMetadata();
    } catch (const std::exception& e) {
        throw InputError(msg(path, ": grid descriptors cannot be read (truncated or corrupt file?): ", e.what()));
    }
    auto impl = std::make_unique<Volume::Impl>();
    VolumeInfo& info = impl->info;
    info.path = path;
    info.grid = chooseDensityGrid(path, grids, o.grid);
    checkUniqueName(path, grids, info.grid);
    const std::string where = msg(path, ": grid '", printableLine(info.grid), "'");
    const auto meta = findGrid(grids, info.grid);
    if (const auto count = meta->getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT))
        checkMemory(where, std::uint64_t(count->value()), o);
    impl->density = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(file, path, info.grid));
    openvdb::FloatGrid& density = *impl->density;
    if (density.activeVoxelCount() == 0) throw InputError(msg(where, " has no active voxels"));
    checkMemory(where, density.activeVoxelCount(), o);
    checkFinite(path, density);
    const openvdb::math::Transform& xf = density.transform();
    if (!xf.isLinear() || !xf.hasUniformScale())
        throw InputError(msg(where, ": only linear transforms with cubic voxels are supported"));
    checkWorldScale(where, density);
    if (density.getGridClass() == openvdb::GRID_LEVEL_SET) {
        openvdb::tools::sdfToFogVolume(density);
        info.levelSet = true;
        info.notes.push_back("level set converted to a fog volume (interior 1, linear across the narrow band)");
        // The inside became active tiles (a root tile holds 4096^3 voxels): checked before they are voxelized.
        checkMemory(where, density.activeVoxelCount(), o);
    }
    density.tree().voxelizeActiveTiles();
    // A level set's conversion can leave nothing (a band with no inside); nothing to fit then.
    if (density.activeVoxelCount() == 0) throw InputError(msg(where, " has no active voxels after the conversion to fog"));
    info.voxelSize = xf.voxelSize()[0];
    info.activeVoxels = density.activeVoxelCount();
    const auto range = openvdb::tools::minMax(density.tree());
    info.minValue = range.min();
    info.maxValue = range.max();
    if (info.minValue < 0.0f) throw InputError(msg(where, " has negative values (min ", info.minValue, ")"));
    // Trilinear sampling in the band reads the background as the outside's value.
    if (!(density.background() >= 0.0f && density.background() <= info.maxValue))
        throw InputError(msg(where, " has background ", density.background(), " (the value outside: 0 to the largest value, ",
                             info.maxValue, ")"));
    if (info.maxValue <= 0.0f) throw InputError(msg(where, " holds only zeros: there is nothing to fit or judge"));
    info.ownFile = metaOr<std::string>(*file.getMetadata(), "creator", "") == "splatwarp";
    if (info.ownFile) info.lambdaLpf = metaOr<float>(*file.getMetadata(), "lambda_lpf", 0.0f);
    // It sizes the fit's filter and initial Gaussians: a standard deviation of sqrt(lambda) voxels.
    // We write 0.2; 1e30 was taken and smeared every Gaussian over the whole volume.
    if (!(info.lambdaLpf >= 0.0f && info.lambdaLpf <= kMaxLambdaLpf))
        throw InputError(msg(path, ": metadata lambda_lpf is ", info.lambdaLpf, " (a filter strength: 0 to ",
                             kMaxLambdaLpf, ")"));
    readFeatures(file, grids, o, *impl);
    file.close();
    return Volume(std::move(impl));
}

Volume::Volume(std::unique_ptr<Impl> impl) : mImpl(std::move(impl)) {}
Volume::~Volume() = default;
Volume::Volume(Volume&&) noexcept = default;
Volume& Volume::operator=(Volume&&) noexcept = default;
const VolumeInfo& Volume::info() const { return mImpl->info; }
int Volume::featureStride() const { return 3 * shCoeffCount(mImpl->info.shDegree); }

namespace {

/// Features of one voxel or point: F_k from the grids, or O times the constant colour.
template <typename FeatureAt>
void writeFeatures(const Volume::Impl& v, float o, const FeatureAt& at, float* f)
{
    if (v.features.empty()) {
        f[0] = f[1] = f[2] = o * v.constantSh;
        return;
    }
    for (std::size_t k = 0; k < v.features.size(); ++k) {
        const openvdb::Vec3s x = at(k);
        for (int c = 0; c < 3; ++c) f[3 * k + std::size_t(c)] = x[c];
    }
}

/// Every voxel of the density's topology dilated by `band`, in leaf order; cell = leaf index.
openvdb::MaskGrid::Ptr sampleMask(const openvdb::FloatGrid& density, int band)
{
    auto mask = openvdb::MaskGrid::create();
    mask->setTransform(density.transform().copy());
    mask->tree().topologyUnion(density.tree());
    if (band > 0)
        openvdb::tools::dilateActiveValues(mask->tree(), band, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                           openvdb::tools::EXPAND_TILES);
    return mask;
}

std::size_t samplesIn(const openvdb::MaskGrid& mask, int perAxis)
{
    return std::size_t(mask.activeVoxelCount()) * std::size_t(perAxis) * std::size_t(perAxis) * std::size_t(perAxis);
}

} // namespace

std::size_t Volume::sampleCount(int band, int perAxis) const
{
    return samplesIn(*sampleMask(*mImpl->density, band), perAxis);
}

void Volume::sample(const float* points, std::size_t m, float* density, float* features) const
{
    const Impl& v = *mImpl;
    const int stride = featureStride();
    parallelForRange(m, 1024, /*threaded=*/true, [&](std::size_t begin, std::size_t end) {
        using FloatSampler = openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler>;
        using VecSampler = openvdb::tools::GridSampler<openvdb::Vec3SGrid::ConstAccessor, openvdb::tools::BoxSampler>;
        // The samplers hold references to the accessors: keep them alive (and unmoved) here.
        const openvdb::FloatGrid::ConstAccessor da = v.density->getConstAccessor();
        FloatSampler ds(da, v.density->transform());
        std::vector<openvdb::Vec3SGrid::ConstAccessor> fa;
        fa.reserve(v.features.size());
        for (const auto& g : v.features) fa.push_back(g->getConstAccessor());
        std::vector<VecSampler> fs;
        for (std::size_t k = 0; k < fa.size(); ++k) fs.emplace_back(fa[k], v.features[k]->transform());
        for (std::size_t j = begin; j != end; ++j) {
            const openvdb::Vec3d p(points[3 * j], points[3 * j + 1], points[3 * j + 2]);
            const float o = ds.wsSample(p);
            density[j] = o;
            if (features)
                writeFeatures(v, o, [&](std::size_t k) { return fs[k].wsSample(p); }, features + j * std::size_t(stride));
        }
    });
}

VoxelSamples Volume::activeVoxels() const
{
    const Impl& v = *mImpl;
    VoxelSamples out;
    out.voxelSize = v.info.voxelSize;
    out.shDegree = v.info.shDegree;
    const std::size_t stride = std::size_t(featureStride());
    std::vector<openvdb::Vec3SGrid::ConstAccessor> fa;
    for (const auto& g : v.features) fa.push_back(g->getConstAccessor());
    for (auto it = v.density->cbeginValueOn(); it; ++it) {
        const openvdb::Vec3d p = v.density->indexToWorld(it.getCoord());
        for (int a = 0; a < 3; ++a) out.positions.push_back(float(p[a]));
        out.values.push_back(*it);
        out.features.resize(out.features.size() + stride);
        writeFeatures(v, *it, [&](std::size_t k) { return fa[k].getValue(it.getCoord()); },
                      out.features.data() + out.features.size() - stride);
    }
    return out;
}

SampleSet Volume::sampleSet(int band, int perAxis) const
{
    if (perAxis < 1) throw InputError(msg(mImpl->info.path, ": samples per voxel axis must be >= 1"));
    const Impl& v = *mImpl;
    const openvdb::MaskGrid::Ptr mask = sampleMask(*v.density, band);
    SampleSet s;
    const std::size_t m = samplesIn(*mask, perAxis);
    s.restPositions.reserve(3 * m); // grown by push_back they held up to twice this
    s.sampleCell.reserve(m);
    s.shDegree = v.info.shDegree;
    // Cells are 2^3-voxel blocks, their samples consecutive: the engine's sample blocks (up to 64
    // consecutive samples of one cell) are then compact boxes, which its coverage culls well.
    s.samplesPerAxis = 2 * perAxis;
    s.spacing = float(v.info.voxelSize / perAxis);
    s.cellSize = float(2.0 * v.info.voxelSize);
    std::int32_t cell = 0;
    for (auto leaf = mask->tree().cbeginLeaf(); leaf; ++leaf)
        for (int block = 0; block < 64; ++block) {
            const openvdb::Coord base = leaf->origin() + openvdb::Coord(2 * (block >> 4), 2 * ((block >> 2) & 3), 2 * (block & 3));
            bool any = false;
            for (int corner = 0; corner < 8; ++corner) {
                const openvdb::Coord ijk = base + openvdb::Coord(corner >> 2, (corner >> 1) & 1, corner & 1);
                if (!leaf->isValueOn(ijk)) continue;
                any = true;
                for (int a = 0; a < perAxis; ++a)
                    for (int b = 0; b < perAxis; ++b)
                        for (int c = 0; c < perAxis; ++c) {
                            const openvdb::Vec3d offset((a + 0.5) / perAxis - 0.5, (b + 0.5) / perAxis - 0.5, (c + 0.5) / perAxis - 0.5);
                            const openvdb::Vec3d p = v.density->indexToWorld(ijk.asVec3d() + offset);
                            for (int k = 0; k < 3; ++k) s.restPositions.push_back(float(p[k]));
                            s.sampleCell.push_back(cell);
                        }
            }
            cell += any ? 1 : 0;
        }
    s.targetO.resize(s.sampleCell.size());
    s.targetF.resize(s.sampleCell.size() * std::size_t(featureStride()));
    sample(s.restPositions.data(), s.targetO.size(), s.targetO.data(), s.targetF.data());
    s.warpedPositions = s.restPositions;
    s.cellGradient.assign(9 * std::size_t(cell), 0.0f);
    for (std::int32_t c = 0; c < cell; ++c)
        for (int d = 0; d < 3; ++d) s.cellGradient[9 * std::size_t(c) + 4 * std::size_t(d)] = 1.0f;
    s.cellSkip.assign(std::size_t(cell), 0);
    return s;
}

std::vector<float> Volume::heldOutPoints(std::size_t count, std::uint32_t seed, int band) const
{
    const openvdb::MaskGrid::Ptr mask = sampleMask(*mImpl->density, band);
    std::vector<openvdb::Coord> voxels;
    voxels.reserve(mask->activeVoxelCount());
    for (auto it = mask->cbeginValueOn(); it; ++it) voxels.push_back(it.getCoord());
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::size_t> pick(0, voxels.size() - 1);
    std::uniform_real_distribution<double> jitter(-0.5, 0.5);
    std::vector<float> points(3 * count);
    for (std::size_t j = 0; j < count; ++j) {
        const openvdb::Coord c = voxels[pick(rng)];
        const openvdb::Vec3d index(c.x() + jitter(rng), c.y() + jitter(rng), c.z() + jitter(rng));
        const openvdb::Vec3d p = mImpl->density->indexToWorld(index);
        for (int a = 0; a < 3; ++a) points[3 * j + std::size_t(a)] = float(p[a]);
    }
    return points;
}

void Volume::worldBounds(Vec3d& lo, Vec3d& hi) const
{
    const openvdb::CoordBBox box = mImpl->density->evalActiveVoxelBoundingBox();
    lo = Vec3d(1e300, 1e300, 1e300);
    hi = Vec3d(-1e300, -1e300, -1e300);
    for (int corner = 0; corner < 8; ++corner) {
        const openvdb::Vec3d index((corner & 1 ? box.max().x() + 1.0 : box.min().x() - 1.0),
                                   (corner & 2 ? box.max().y() + 1.0 : box.min().y() - 1.0),
                                   (corner & 4 ? box.max().z() + 1.0 : box.min().z() - 1.0));
        const openvdb::Vec3d p = mImpl->density->indexToWorld(index);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
}

} // namespace splatwarp

namespace splatwarp {

namespace {
template <typename GridT, typename V>
typename GridT::Ptr denseToGrid(const DenseGrid& d, const V& convert)
{
    // A level set's background is its band's half width (OpenVDB's convention; sdfToFogVolume reads it).
    float band = 0.0f;
    if (d.levelSet)
        for (float v : d.values) band = std::max(band, std::fabs(v));
    auto g = d.levelSet ? GridT::create(convert(band)) : GridT::create();
    g->setName(d.name);
    g->setTransform(openvdb::math::Transform::createLinearTransform(d.voxelSize));
    g->setGridClass(d.levelSet ? openvdb::GRID_LEVEL_SET : openvdb::GRID_FOG_VOLUME);
    auto acc = g->getAccessor();
    std::size_t n = 0;
    for (int z = 0; z < d.dims[2]; ++z)
        for (int y = 0; y < d.dims[1]; ++y)
            for (int x = 0; x < d.dims[0]; ++x, ++n)
                if (d.values[n] != 0.0f || std::isnan(d.values[n]))
                    acc.setValue(openvdb::Coord(d.origin[0] + x, d.origin[1] + y, d.origin[2] + z), convert(d.values[n]));
    if (d.fillVoxels > 0) {
        const openvdb::Coord lo(d.origin[0], d.origin[1], d.origin[2]);
        g->tree().sparseFill(openvdb::CoordBBox(lo, lo.offsetBy(d.fillVoxels - 1)), convert(d.fillValue), true);
    }
    return g;
}
} // namespace

void writeDenseGrids(const std::string& path, const std::vector<DenseGrid>& grids)
{
    vdb::initialize();
    openvdb::GridPtrVec out;
    for (const DenseGrid& d : grids) {
        if (d.values.size() != std::size_t(d.dims[0]) * std::size_t(d.dims[1]) * std::size_t(d.dims[2]))
            throw InputError(msg(path, ": grid '", d.name, "' has ", d.values.size(), " values for its dimensions"));
        if (d.vector)
            out.push_back(denseToGrid<openvdb::Vec3SGrid>(d, [](float v) { return openvdb::Vec3s(v); }));
        else
            out.push_back(denseToGrid<openvdb::FloatGrid>(d, [](float v) { return v; }));
    }
    AtomicFile file(path);
    try {
        openvdb::io::File f(file.tempPath());
        f.write(out);
        f.close();
    } catch (const openvdb::Exception& e) {
        throw IoError(msg(path, ": cannot write the VDB file: ", e.what()));
    }
    settleVdbFileUuid(file.tempPath());
    file.commit();
}

} // namespace splatwarp
