/// libFuzzer target: the SOG reader. The input is read as a `.sog` bundle as is, and again as the
/// meta.json of a bundle whose images are those of an 8-Gaussian model this target writes once with
/// our writer, so that mutations reach the meta.json checks and the image decoders past the zip.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "FuzzBytes.h"
#include "io/SogFormat.h"
#include "io/SogIO.h"

namespace {

using Files = std::vector<std::pair<std::string, std::string>>;

void read(const std::string& bytes) { fuzz::readQuietly(splatwarp::readSog, bytes); }

const Files& seedImages()
{
    static const Files files = [] {
        splatwarp::GaussianCloud g;
        g.resize(8, 1);
        for (std::size_t i = 0; i < g.means.size(); ++i) g.means[i] = float(i % 7) * 0.3f - 1.0f;
        for (std::size_t i = 0; i < g.sh.size(); ++i) g.sh[i] = float(i % 5) * 0.1f;
        return splatwarp::encodeSogFiles("seed.sog", g);
    }();
    return files;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    read(bytes);
    Files files = seedImages();
    files.back().second = bytes; // meta.json is written last
    read(splatwarp::sog::storedZip(files));
    return 0;
}
