// See BoxBinsProbe.h.
#include "kernels/BoxBinsProbe.h"

#include "kernels/BoxBinsCuda.cuh"

namespace splatwarp::cuda {

BoxBinsProbe probeBoxBins(const std::vector<float>& lo, const std::vector<float>& hi)
{
    if (lo.size() != hi.size() || lo.size() % 3 != 0)
        throw InputError(msg("probeBoxBins: ", lo.size(), " low and ", hi.size(), " high corner floats"));
    StreamHolder stream;
    DeviceBuffer<float> dLo("probe box corners"), dHi("probe box corners");
    dLo.upload(lo, stream.stream);
    dHi.upload(hi, stream.stream);
    BoxBins bins;
    BoxBinsProbe p;
    p.built = bins.build(lo.size() / 3, dLo.data(), dHi.data(), stream.stream, "probeBoxBins");
    p.entries = bins.entries();
    p.inv = bins.inv();
    SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(stream.stream));
    return p;
}

} // namespace splatwarp::cuda
