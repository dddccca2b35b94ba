/// Gaussian models as OpenVDB PointDataGrids with Houdini's GSplat attribute names (VdbPoints.h):
/// writing, reading (any codec of P; id restores the order), and the registration as a model format.
#include "vdb/VdbPoints.h"

#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/points/PointDataGrid.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "vdb/VdbLayout.h"
#include "vdb/VdbLibrary.h"
#include "core/AtomicFile.h"
#include "core/Error.h"
#include "sh/SphericalHarmonics.h"

namespace splatwarp {

namespace {

namespace pts = openvdb::points;
using openvdb::Vec3f;
using Quats = openvdb::math::Quat<float>;
const char* const kSh[3] = {"GS_SPH_R", "GS_SPH_G", "GS_SPH_B"};

// Copies one attribute into the grid, in the order of the point index grid.
template <typename T>
void addAttribute(pts::PointDataGrid& grid, const openvdb::tools::PointIndexGrid& index, const std::string& name,
                  const std::vector<T>& values, openvdb::Index stride = 1)
{
    pts::appendAttribute<T>(grid.tree(), name, openvdb::zeroVal<T>(), stride);
    pts::populateAttribute(grid.tree(), index.tree(), name, pts::PointAttributeVector<T>(values, stride), stride);
}

pts::PointDataGrid::Ptr buildGrid(const std::string& path, const GaussianCloud& g)
{
    const std::size_t n = g.size();
    std::vector<Vec3f> p(n), scale(n), cd(n);
    std::vector<Quats> orient(n);
    std::vector<float> alpha(n);
    std::vector<std::vector<float>> sh(3, std::vector<float>(n * std::size_t(g.shCoeffs())));
    std::vector<openvdb::Int32> id(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Quatf q = g.rotation(i);
        const double norm = std::sqrt(double(q.w) * q.w + double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
        orient[i] = Quats(float(q.x / norm), float(q.y / norm), float(q.z / norm), float(q.w / norm)); // x y z w
        for (int a = 0; a < 3; ++a) {
            p[i][a] = g.means[3 * i + a];
            scale[i][a] = float(std::exp(double(g.logScales[3 * i + a])));
            cd[i][a] = float(0.5 + kShC0 * g.shOf(i)[a]);
            for (int j = 0; j < g.shCoeffs(); ++j) sh[a][i * g.shCoeffs() + j] = g.shOf(i)[3 * j + a];
        }
        alpha[i] = float(sigmoid(double(g.opacities[i])));
        id[i] = openvdb::Int32(i);
    }
    const pts::PointAttributeVector<Vec3f> positions(p);
    const float voxel = std::max(pts::computeVoxelSize(positions, 8), 1e-6f); // about 8 points a voxel
    // OpenVDB's voxel coordinates are int32: centres at 1e12 were written at coordinate -2^31,
    // which OpenVDB's tools place wrongly (ours read the offsets back).
    double far = 0;
    for (const Vec3f& c : p) far = std::max({far, std::abs(double(c.x())), std::abs(double(c.y())), std::abs(double(c.z()))});
    if (far / voxel > double(1 << 30))
        throw InputError(msg(path, ": a centre ", far, " from the origin is ", far / voxel, " voxels of ", voxel,
                             " away, beyond OpenVDB's 32-bit voxel coordinates (convert --drop-outliers drops far centres)"));
    const auto transform = openvdb::math::Transform::createLinearTransform(voxel);
    const auto index = openvdb::tools::createPointIndexGrid<openvdb::tools::PointIndexGrid>(positions, *transform);
    // NullCodec: voxel-relative float32 positions (no quantisation).
    auto grid = pts::createPointDataGrid<pts::NullCodec, pts::PointDataGrid>(*index, positions, *transform);
    addAttribute(*grid, *index, "orient", orient);
    addAttribute(*grid, *index, "scale", scale);
    addAttribute(*grid, *index, "Cd", cd);
    addAttribute(*grid, *index, "GS_Alpha", alpha);
    for (int c = 0; c < 3; ++c) addAttribute(*grid, *index, kSh[c], sh[c], openvdb::Index(g.shCoeffs()));
    addAttribute(*grid, *index, "id", id);
    grid->setName("splats");
    grid->insertMeta("splatwarp_sh_degree", openvdb::Int32Metadata(g.shDegree));
    return grid;
}

// A named attribute of one leaf, or none.
template <typename T>
std::unique_ptr<pts::AttributeHandle<T>> handle(const pts::PointDataTree::LeafNodeType& leaf, const char* name)
{
    const std::size_t pos = leaf.attributeSet().find(name);
    if (pos == pts::AttributeSet::INVALID_POS) return nullptr;
    return std::make_unique<pts::AttributeHandle<T>>(leaf.constAttributeArray(pos));
}

float logitOf(double a)
{
    a = std::min(std::max(a, 1e-38), 1.0 - std::ldexp(1.0, -24)); // 0 and 1 stay finite
    return float(std::log(a / (1 - a)));
}

int shDegreeOf(const pts::PointDataGrid& grid, const pts::PointDataTree::LeafNodeType* leaf)
{
    if (!leaf) return 0;
    const auto r = handle<float>(*leaf, kSh[0]);
    if (!r) return 0;
    const int stride = int(r->stride());
    int degree = 0;
    while (degree < 3 && shCoeffCount(degree + 1) <= stride) ++degree;
    const auto meta = grid.getMetadata<openvdb::Int32Metadata>("splatwarp_sh_degree");
    return meta ? std::clamp(meta->value(), 0, degree) : degree;
}

// Gaussian k of the grid's order into slot `at` of the cloud, from one leaf's handles.
struct LeafReader {
    std::unique_ptr<pts::AttributeHandle<Vec3f>> p, scale, cd;
    std::unique_ptr<pts::AttributeHandle<float>> pscale, alpha, sh[3];
    std::unique_ptr<pts::AttributeHandle<Quats>> orient;
    std::unique_ptr<pts::AttributeHandle<openvdb::Int32>> id;

    explicit LeafReader(const pts::PointDataTree::LeafNodeType& leaf)
        : p(handle<Vec3f>(leaf, "P")), scale(handle<Vec3f>(leaf, "scale")), cd(handle<Vec3f>(leaf, "Cd")),
          pscale(handle<float>(leaf, "pscale")), alpha(handle<float>(leaf, "GS_Alpha")),
          orient(handle<Quats>(leaf, "orient")), id(handle<openvdb::Int32>(leaf, "id"))
    {
        for (int c = 0; c < 3; ++c) sh[c] = handle<float>(leaf, kSh[c]);
    }

    void read(openvdb::Index k, const Vec3f& centre, GaussianCloud& g, std::size_t at) const
    {
        for (int a = 0; a < 3; ++a) {
            g.means[3 * at + a] = centre[a];
            g.logScales[3 * at + a] = float(std::log(double(scale ? scale->get(k)[a] : pscale->get(k))));
            if (sh[a]) {
                for (int j = 0; j < g.shCoeffs() && j < int(sh[a]->stride()); ++j) g.shOf(at)[3 * j + a] = sh[a]->get(k, j);
            } else if (cd) {
                g.shOf(at)[a] = float((double(cd->get(k)[a]) - 0.5) / kShC0);
            }
        }
        g.opacities[at] = logitOf(alpha->get(k));
        if (orient) {
            const Quats q = orient->get(k);
            g.setRotation(at, {q.w(), q.x(), q.y(), q.z()});
        }
    }
};

const pts::PointDataGrid* firstPointGrid(const std::string& name, const openvdb::GridPtrVec& grids)
{
    for (const openvdb::GridBase::Ptr& grid : grids)
        if (const auto* pg = dynamic_cast<const pts::PointDataGrid*>(grid.get())) return pg;
    throw InputError(msg(name, ": an OpenVDB file without a point grid (PointDataGrid); a volume is read by 'from-vdb'"));
}

/// The points of a leaf: its voxels' offsets, which index its attribute arrays, checked against them
/// (a forged offset read out of bounds, or sized the cloud: 1.7 GB for a 12 KB file).
std::size_t checkedPointCount(const std::string& name, const pts::PointDataGrid& grid,
                              const pts::PointDataTree::LeafNodeType& leaf)
{
    try {
        leaf.validateOffsets();
        if (leaf.attributeSet().size() == 0 && leaf.pointCount() > 0)
            OPENVDB_THROW(openvdb::ValueError, "Points without attribute arrays");
    } catch (const openvdb::ValueError& e) {
        throw InputError(msg(name, ": point grid '", printable(grid.getName()), "', leaf at ", leaf.origin(), ": ",
                             e.what(), " (corrupt point offsets)"));
    }
    return std::size_t(leaf.pointCount());
}

GaussianCloud readGrid(const std::string& name, const pts::PointDataGrid& grid, ReadReport& report)
{
    const auto leaf0 = grid.tree().cbeginLeaf();
    std::size_t n = 0;
    for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) n += checkedPointCount(name, grid, *leaf);
    if (n == 0) throw InputError(msg(name, ": the point grid '", printable(grid.getName()), "' holds no points"));
    GaussianCloud g;
    g.resize(n, shDegreeOf(grid, leaf0 ? &*leaf0 : nullptr));
    std::vector<char> taken(n, 0);
    std::size_t at = 0, placed = 0;
    for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
        const LeafReader r(*leaf);
        if (!r.p || !(r.scale || r.pscale) || !r.alpha)
            throw InputError(msg(name, ": point grid '", printable(grid.getName()),
                                 "' lacks P, scale (or pscale) or GS_Alpha, so its points are not Gaussians"));
        for (auto it = leaf->beginIndexOn(); it; ++it, ++at) {
            const Vec3f centre = grid.transform().indexToWorld(it.getCoord().asVec3d() + r.p->get(*it));
            const std::int64_t id = r.id ? r.id->get(*it) : -1;
            const bool useId = id >= 0 && std::size_t(id) < n && !taken[std::size_t(id)];
            const std::size_t slot = useId ? std::size_t(id) : at;
            if (useId) taken[slot] = 1, ++placed;
            r.read(*it, centre, g, slot);
        }
    }
    if (placed != n && placed != 0)
        throw InputError(msg(name, ": point grid ids are not a permutation of 0..", n - 1));
    if (placed == 0) report.notes.push_back("no 'id' attribute: Gaussians in the grid's voxel order");
    return g;
}

bool hasVdbMagic(const std::string& data) { return data.compare(0, 8, std::string(" BDV\0\0\0\0", 8)) == 0; }

GaussianCloud readVdbHook(const std::string& name, const std::string& data, ReadReport& report)
{
    return readVdbPoints(name, data, report);
}

void writeVdbHook(const std::string& path, const GaussianCloud& g) { writeVdbPoints(path, g); }

} // namespace

void writeVdbPoints(const std::string& path, const GaussianCloud& g)
{
    g.checkConsistent();
    checkModelForWriting(path, g);
    if (g.size() > 0x7fffffffu) throw InputError(msg(path, ": ", g.size(), " Gaussians exceed the 2^31 - 1 ids"));
    vdb::initialize();
    std::ostringstream os(std::ios::binary);
    try {
        openvdb::GridPtrVec grids = {buildGrid(path, g)};
        openvdb::io::Stream(os).write(grids);
    } catch (const openvdb::Exception& e) {
        throw IoError(msg(path, ": cannot write the point grid: ", e.what()));
    }
    std::string bytes = os.str();
    settleVdbUuid(bytes);
    writeFileAtomic(path, bytes);
}

GaussianCloud readVdbPoints(const std::string& name, const std::string& data, ReadReport& report)
{
    vdb::initialize();
    try {
        std::istringstream is(data, std::ios::binary);
        checkVdbLayout(is, data.size(), name); // before OpenVDB, which reads garbage sizes from a cut file
        is.clear();
        is.seekg(0);
        // Read from the bytes themselves, a short read an exception: with delayed loading (the
        // default) OpenVDB copied them to a file and read pages later, and a cut file failed an
        // assertion in Page::readHeader (exit 134) on an unread size.
        is.exceptions(std::ios::failbit | std::ios::badbit | std::ios::eofbit);
        openvdb::io::Stream stream(is, /*delayLoad=*/false);
        const openvdb::GridPtrVecPtr grids = stream.getGrids();
        GaussianCloud g = readGrid(name, *firstPointGrid(name, *grids), report);
        report.format = "vdb-points";
        return g;
    } catch (const openvdb::Exception& e) {
        throw InputError(msg(name, ": not a readable OpenVDB point file: ", e.what()));
    } catch (const std::bad_alloc&) {
        throw InputError(msg(name, ": not a readable OpenVDB point file: corrupt sizes (allocation failed)"));
    } catch (const std::length_error& e) {
        throw InputError(msg(name, ": not a readable OpenVDB point file: corrupt sizes (", e.what(), ")"));
    } catch (const std::ios_base::failure&) {
        throw InputError(msg(name, ": not a readable OpenVDB point file: it ends inside its data (truncated or corrupt file?)"));
    }
}

void registerVdbPointFormat()
{
    ModelFormatHooks hooks;
    hooks.name = "vdb-points";
    hooks.extension = ".vdb";
    hooks.detect = hasVdbMagic;
    hooks.read = readVdbHook;
    hooks.write = writeVdbHook;
    registerModelFormat(hooks);
}

} // namespace splatwarp
