#include "support/VdbFileReader.h"

#include <openvdb/openvdb.h>

#include "vdb/VdbLibrary.h"
#include "core/Error.h"

namespace splatwarp::test {

const VdbGridData* VdbFileData::find(const std::string& name) const
{
    for (const VdbGridData& g : grids)
        if (g.name == name) return &g;
    return nullptr;
}

namespace {

std::map<std::string, std::string> metaStrings(const openvdb::MetaMap& meta)
{
    std::map<std::string, std::string> out;
    for (auto it = meta.beginMeta(); it != meta.endMeta(); ++it) out[it->first] = it->second->str();
    return out;
}

/// Channel k of a scalar or vector value as float.
template <typename T>
float channel(const T& v, int) { return float(v); }
float channel(const openvdb::Vec3s& v, int k) { return v[k]; }

template <typename GridT>
bool readValues(const openvdb::GridBase::Ptr& base, VdbGridData& out)
{
    typename GridT::Ptr g = openvdb::GridBase::grid<GridT>(base);
    if (!g) return false;
    using ValueT = typename GridT::ValueType;
    out.channels = openvdb::VecTraits<ValueT>::Size;
    for (auto it = g->cbeginValueOn(); it; ++it) {
        // Tiles are expanded so every active voxel is listed.
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        for (auto c = box.begin(); c; ++c) {
            const openvdb::Coord ijk = *c;
            for (int k = 0; k < 3; ++k) out.coords.push_back(ijk[k]);
            const ValueT v = *it;
            for (int k = 0; k < out.channels; ++k) out.values.push_back(channel(v, k));
        }
    }
    return true;
}

bool readMask(const openvdb::GridBase::Ptr& base, VdbGridData& out)
{
    openvdb::MaskGrid::Ptr g = openvdb::GridBase::grid<openvdb::MaskGrid>(base);
    if (!g) return false;
    for (auto it = g->cbeginValueOn(); it; ++it) {
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        for (auto c = box.begin(); c; ++c)
            for (int k = 0; k < 3; ++k) out.coords.push_back((*c)[k]);
    }
    return true;
}

} // namespace

VdbFileData readVdbFile(const std::string& path)
{
    vdb::initialize();
    VdbFileData data;
    try {
        openvdb::io::File file(path);
        file.open();
        data.metadata = metaStrings(*file.getMetadata());
        openvdb::GridPtrVecPtr grids = file.getGrids();
        file.close();
        for (const openvdb::GridBase::Ptr& base : *grids) {
            VdbGridData g;
            g.name = base->getName();
            g.valueType = base->valueType();
            g.gridClass = openvdb::GridBase::gridClassToString(base->getGridClass());
            g.voxelSize = base->voxelSize()[0];
            const openvdb::Vec3d o = base->indexToWorld(openvdb::Coord(0, 0, 0));
            for (int k = 0; k < 3; ++k) g.origin[k] = o[k];
            g.savedAsHalf = base->saveFloatAsHalf();
            g.metadata = metaStrings(*base);
            readValues<openvdb::FloatGrid>(base, g) || readValues<openvdb::DoubleGrid>(base, g) ||
                readValues<openvdb::Int32Grid>(base, g) || readValues<openvdb::Vec3SGrid>(base, g) ||
                readValues<openvdb::BoolGrid>(base, g) || readMask(base, g);
            data.grids.push_back(std::move(g));
        }
    } catch (const openvdb::Exception& e) {
        throw IoError(msg(path, ": cannot read the VDB file: ", e.what()));
    }
    return data;
}

namespace {

void rewriteFileMetadata(const std::string& path, const std::string& key, const openvdb::Metadata& value)
{
    vdb::initialize();
    try {
        openvdb::io::File in(path);
        in.open();
        openvdb::MetaMap::Ptr meta = in.getMetadata();
        openvdb::GridPtrVecPtr grids = in.getGrids();
        in.close();
        meta->removeMeta(key);
        meta->insertMeta(key, value);
        openvdb::io::File out(path);
        out.write(*grids, *meta);
        out.close();
    } catch (const openvdb::Exception& e) {
        throw IoError(msg(path, ": cannot rewrite the VDB file: ", e.what()));
    }
}

} // namespace

void setFileMetadata(const std::string& path, const std::string& key, float value)
{
    rewriteFileMetadata(path, key, openvdb::FloatMetadata(value));
}

void setFileMetadataInt(const std::string& path, const std::string& key, std::int32_t value)
{
    rewriteFileMetadata(path, key, openvdb::Int32Metadata(value));
}

} // namespace splatwarp::test
