/// libFuzzer target: reading Gaussians from an OpenVDB point grid (vdb/VdbPoints.cpp). The input
/// builds a PointDataGrid (up to 64 points: raw float positions and attribute values, which
/// attributes exist, the SH stride, ids that may repeat or leave the range), which this target
/// serialises with OpenVDB and hands to readGaussiansFromBytes() as the CLI would. The raw input is
/// not parsed as a .vdb: OpenVDB's own stream reader trusts the sizes in the file (a huge one is an
/// allocation ASan aborts on; outside ASan it is a std::bad_alloc that the reader reports) and leaks
/// a node when a read throws, which are the library's, not ours (docs/robustness.md).
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "vdb/VdbLibrary.h"
#include "vdb/VdbPoints.h"
#include "core/Error.h"
#include "io/GaussianIO.h"

namespace {

namespace pts = openvdb::points;

struct Input {
    const std::uint8_t* p;
    std::size_t left;
    float f()
    {
        float v = 0;
        if (left >= 4) std::memcpy(&v, p, 4), p += 4, left -= 4;
        return v;
    }
    std::uint8_t byte() { return left ? (--left, *p++) : 0; }
};

template <typename T>
void add(pts::PointDataGrid& grid, const openvdb::tools::PointIndexGrid& index, const char* name,
         const std::vector<T>& values, openvdb::Index stride = 1)
{
    pts::appendAttribute<T>(grid.tree(), name, openvdb::zeroVal<T>(), stride);
    pts::populateAttribute(grid.tree(), index.tree(), name, pts::PointAttributeVector<T>(values, stride), stride);
}

std::string buildVdb(Input in)
{
    const std::uint8_t flags = in.byte(), stride = std::uint8_t(1 + in.byte() % 20);
    const std::size_t n = 1 + in.byte() % 64;
    std::vector<openvdb::Vec3f> p(n), scale(n), cd(n);
    std::vector<openvdb::math::Quat<float>> orient(n);
    std::vector<float> alpha(n), sh(n * stride);
    std::vector<openvdb::Int32> id(n);
    for (std::size_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) p[i][a] = float(in.byte()) / 16, scale[i][a] = in.f(), cd[i][a] = in.f();
        orient[i] = openvdb::math::Quat<float>(in.f(), in.f(), in.f(), in.f());
        alpha[i] = in.f();
        for (std::size_t j = 0; j < stride; ++j) sh[i * stride + j] = in.f();
        id[i] = flags & 64 ? openvdb::Int32(std::int8_t(in.byte())) : openvdb::Int32(i);
    }
    const pts::PointAttributeVector<openvdb::Vec3f> positions(p);
    const auto transform = openvdb::math::Transform::createLinearTransform(flags & 128 ? 0.5 : 4.0);
    const auto index = openvdb::tools::createPointIndexGrid<openvdb::tools::PointIndexGrid>(positions, *transform);
    auto grid = pts::createPointDataGrid<pts::NullCodec, pts::PointDataGrid>(*index, positions, *transform);
    if (flags & 1) add(*grid, *index, "scale", scale);
    if (flags & 2) add(*grid, *index, "GS_Alpha", alpha);
    if (flags & 4) add(*grid, *index, "orient", orient);
    if (flags & 8) add(*grid, *index, "Cd", cd);
    if (flags & 16)
        for (const char* name : {"GS_SPH_R", "GS_SPH_G", "GS_SPH_B"}) add(*grid, *index, name, sh, stride);
    if (flags & 32) add(*grid, *index, "id", id);
    std::ostringstream os(std::ios::binary);
    openvdb::io::Stream(os).write(openvdb::GridPtrVec{grid});
    return os.str();
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    splatwarp::vdb::initialize();
    splatwarp::registerVdbPointFormat();
    const std::string vdb = buildVdb(Input{data, size});
    try {
        splatwarp::readGaussiansFromBytes("fuzz-input", vdb);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
