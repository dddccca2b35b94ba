/// libFuzzer target: readVolume() of a `.vdb` whose grids and metadata the input chooses (our
/// own files' "creator", "sh_degree", "lambda_lpf"; grid names, classes, transforms, values,
/// NaN and negative ones included). OpenVDB writes a valid file from them, so what is fuzzed is
/// our reading of what a file claims, not OpenVDB's byte parser.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <unistd.h>

#include <openvdb/openvdb.h>

#include "vdb/Volume.h"
#include "core/Error.h"

namespace {

/// The input read as a stream of small fields (zeros past its end).
struct Input {
    const std::uint8_t* data;
    std::size_t size, at = 0;
    std::uint8_t byte() { return at < size ? data[at++] : 0; }
    template <typename T>
    T value()
    {
        T v{};
        std::uint8_t b[sizeof(T)];
        for (std::uint8_t& x : b) x = byte();
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
};

openvdb::GridPtrVec makeGrids(Input& in, openvdb::MetaMap& meta)
{
    const std::uint8_t flags = in.byte();
    const double voxel = 0.01 + (in.byte() % 16) * 0.05;
    auto xf = openvdb::math::Transform::createLinearTransform(voxel);
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.0f);
    density->setName((flags & 1) ? "density" : "smoke");
    density->setTransform(xf);
    if (flags & 2) density->setGridClass(openvdb::GRID_LEVEL_SET);
    const int voxels = in.byte() % 48;
    for (int i = 0; i < voxels; ++i)
        density->tree().setValueOn(openvdb::Coord(in.byte() % 8, in.byte() % 8, in.byte() % 8), in.value<float>());
    openvdb::GridPtrVec grids{density};
    const int shGrids = (flags >> 4) % 17;
    for (int k = 0; k < shGrids; ++k) {
        auto g = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
        g->setName("sh_" + std::to_string(k));
        g->setTransform((flags & 4) ? xf : openvdb::math::Transform::createLinearTransform(voxel * 2));
        g->tree().setValueOn(openvdb::Coord(0, 0, 0), openvdb::Vec3s(in.value<float>(), 0.5f, -0.5f));
        grids.push_back(g);
    }
    if (flags & 8) {
        auto c = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
        c->setName("color");
        c->setTransform(xf);
        c->tree().setValueOn(openvdb::Coord(1, 1, 1), openvdb::Vec3s(in.value<float>(), 1.0f, 0.0f));
        grids.push_back(c);
    }
    if (in.byte() & 1) meta.insertMeta("creator", openvdb::StringMetadata("splatwarp"));
    meta.insertMeta("sh_degree", openvdb::Int32Metadata(in.value<std::int32_t>()));
    meta.insertMeta("lambda_lpf", openvdb::FloatMetadata(in.value<float>()));
    return grids;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    openvdb::initialize();
    static const std::string path = "/tmp/splatwarp-fuzz-vdb-" + std::to_string(::getpid()) + ".vdb";
    Input in{data, size};
    openvdb::MetaMap meta;
    const openvdb::GridPtrVec grids = makeGrids(in, meta);
    openvdb::io::File(path).write(grids, meta);
    try {
        splatwarp::VolumeReadOptions options;
        options.memoryLimit = std::uint64_t(1) << 30;
        const splatwarp::Volume volume = splatwarp::readVolume(path, options);
        // What from-vdb takes from it next: the voxels with their features and a sample lattice.
        const splatwarp::VoxelSamples voxels = volume.activeVoxels();
        const splatwarp::SampleSet samples = volume.sampleSet(1, 1);
        (void)voxels;
        (void)samples;
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
