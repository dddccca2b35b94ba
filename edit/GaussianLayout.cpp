#include "edit/GaussianLayout.h"

#include <cstring>

#include "core/Error.h"

namespace splatwarp::edit {

namespace {

static_assert(sizeof(float) == 4, "the layout is float32");

void putU32(std::string& out, std::size_t at, std::uint32_t v)
{
    const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                                static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
    std::memcpy(out.data() + at, b, 4);
}

std::uint32_t getU32(const std::string& in, std::size_t at)
{
    const auto* b = reinterpret_cast<const unsigned char*>(in.data() + at);
    return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24;
}

} // namespace

namespace {

std::string encodeArrays(const GaussianCloud& cloud, int modelShDegree, std::size_t floats)
{
    const std::size_t n = cloud.size();
    std::string out(kLayoutHeaderBytes + n * floats * 4, '\0');
    std::memcpy(out.data(), kLayoutMagic, 4);
    putU32(out, 4, std::uint32_t(n));
    putU32(out, 8, std::uint32_t(floats));
    putU32(out, 12, std::uint32_t(modelShDegree < 0 ? cloud.shDegree : modelShDegree));
    // x86-64 and aarch64 are little-endian: the arrays are copied as they are.
    char* at = out.data() + kLayoutHeaderBytes;
    const auto put = [&](const float* data, std::size_t count) {
        if (count) std::memcpy(at, data, count * 4);
        at += count * 4;
    };
    put(cloud.means.data(), 3 * n);
    put(cloud.rotations.data(), 4 * n);
    put(cloud.logScales.data(), 3 * n);
    if (floats == kPoseFloats) return out;
    put(cloud.opacities.data(), n);
    const std::size_t stride = std::size_t(cloud.shStride());
    for (std::size_t i = 0; i < n; ++i) put(cloud.sh.data() + i * stride, 3); // coefficient 0: f_dc
    return out;
}

} // namespace

std::string encodeGaussians(const GaussianCloud& cloud, int modelShDegree)
{
    return encodeArrays(cloud, modelShDegree, kLayoutFloats);
}

std::string encodePose(const GaussianCloud& cloud, int modelShDegree)
{
    return encodeArrays(cloud, modelShDegree, kPoseFloats);
}

GaussianCloud decodeGaussians(const std::string& bytes, const GaussianCloud* rest)
{
    if (bytes.size() < kLayoutHeaderBytes || std::memcmp(bytes.data(), kLayoutMagic, 4) != 0)
        throw InputError("not an SWG1 model buffer");
    const std::size_t n = getU32(bytes, 4), floats = getU32(bytes, 8);
    if ((floats != kLayoutFloats && floats != kPoseFloats) || bytes.size() != kLayoutHeaderBytes + n * floats * 4)
        throw InputError(msg("SWG1 buffer of ", bytes.size(), " bytes does not hold ", n, " Gaussians"));
    if (floats == kPoseFloats && (!rest || rest->size() != n))
        throw InputError(msg("an SWG1 pose of ", n, " Gaussians holds no opacities or colours: decode it with its rest model"));
    GaussianCloud cloud;
    if (floats == kPoseFloats) cloud = withShDegree(*rest, 0); // its opacities and DC; the geometry below
    else cloud.resize(n, 0);
    const char* at = bytes.data() + kLayoutHeaderBytes;
    const auto get = [&](float* data, std::size_t count) {
        if (count) std::memcpy(data, at, count * 4);
        at += count * 4;
    };
    get(cloud.means.data(), 3 * n);
    get(cloud.rotations.data(), 4 * n);
    get(cloud.logScales.data(), 3 * n);
    if (floats == kLayoutFloats) {
        get(cloud.opacities.data(), n);
        get(cloud.sh.data(), 3 * n);
    }
    return cloud;
}

} // namespace splatwarp::edit
