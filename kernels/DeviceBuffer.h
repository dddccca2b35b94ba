#pragma once
/// @file DeviceBuffer.h
/// @brief RAII device memory for n elements of T. Allocation failures throw DeviceMemoryError
///        naming what did not fit, the bytes asked for and the bytes free, never crash.
#include <cuda_runtime.h>

#include <atomic>
#include <cstddef>
#include <utility>
#include <vector>

#include "kernels/CudaCheck.h"

namespace splatwarp::cuda {

namespace detail {
/// Bytes held by all DeviceBuffers now, and the most held since the last resetDeviceBytesPeak().
inline std::atomic<std::size_t>& deviceBytesNow()
{
    static std::atomic<std::size_t> bytes{0};
    return bytes;
}
inline std::atomic<std::size_t>& deviceBytesMax()
{
    static std::atomic<std::size_t> bytes{0};
    return bytes;
}
inline void countDeviceBytes(std::size_t added)
{
    const std::size_t now = deviceBytesNow().fetch_add(added) + added;
    std::size_t peak = deviceBytesMax().load();
    while (now > peak && !deviceBytesMax().compare_exchange_weak(peak, now)) {
    }
}
} // namespace detail

/// @brief Peak GPU memory held by DeviceBuffers since the last resetDeviceBytesPeak() (the
///        project's own allocations, CUB temporaries included; not the CUDA context).
inline std::size_t deviceBytesPeak() { return detail::deviceBytesMax().load(); }
/// @brief Start a new peak measurement from what is held now.
inline void resetDeviceBytesPeak() { detail::deviceBytesMax().store(detail::deviceBytesNow().load()); }

template <typename T>
class DeviceBuffer {
public:
    /// @param what  names the buffer in error messages ("coverage pairs")
    explicit DeviceBuffer(const char* what = "device buffer") : mWhat(what) {}
    DeviceBuffer(std::size_t n, const char* what) : mWhat(what) { resize(n); }
    ~DeviceBuffer() { release(); }
    DeviceBuffer(const DeviceBuffer&) = delete;
    DeviceBuffer& operator=(const DeviceBuffer&) = delete;
    DeviceBuffer(DeviceBuffer&& o) noexcept { swap(o); }
    DeviceBuffer& operator=(DeviceBuffer&& o) noexcept
    {
        if (this != &o) {
            release();
            swap(o);
        }
        return *this;
    }

    /// @brief Hold n elements. Reallocates (contents lost) only when n exceeds the capacity, so
    ///        buffers resized every coverage rebuild settle at their largest size.
    void resize(std::size_t n)
    {
        if (n > mCapacity) {
            release();
            const std::size_t bytes = n * sizeof(T);
            void* p = nullptr;
            const cudaError_t e = cudaMalloc(&p, bytes);
            if (e != cudaSuccess) {
                cudaGetLastError(); // clear the (non-sticky) allocation error
                std::size_t free = 0, total = 0;
                cudaMemGetInfo(&free, &total);
                const std::string text = msg("CUDA: cannot allocate ", bytes, " bytes of GPU memory for ", mWhat,
                                             " (", free, " of ", total, " bytes free): ", cudaGetErrorString(e));
                if (e == cudaErrorMemoryAllocation) throw DeviceMemoryError(text);
                throw Error(text);
            }
            mData = static_cast<T*>(p);
            mCapacity = n;
            detail::countDeviceBytes(bytes);
        }
        mSize = n;
    }
    /// @brief resize(v.size()) and copy v in (asynchronous on stream; v must outlive the copy,
    ///        or the stream be synchronised, before v changes).
    void upload(const std::vector<T>& v, cudaStream_t stream)
    {
        resize(v.size());
        if (!v.empty())
            SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(mData, v.data(), v.size() * sizeof(T), cudaMemcpyHostToDevice, stream));
    }
    /// @brief Copy the first n elements out and wait for them.
    void download(T* out, std::size_t n, cudaStream_t stream) const
    {
        if (n == 0) return;
        SPLATWARP_CUDA_CHECK(cudaMemcpyAsync(out, mData, n * sizeof(T), cudaMemcpyDeviceToHost, stream));
        SPLATWARP_CUDA_CHECK(cudaStreamSynchronize(stream));
    }
    std::vector<T> download(cudaStream_t stream) const
    {
        std::vector<T> v(mSize);
        download(v.data(), mSize, stream);
        return v;
    }

    T* data() { return mData; }
    const T* data() const { return mData; }
    std::size_t size() const { return mSize; }
    std::size_t bytes() const { return mSize * sizeof(T); }

private:
    void release()
    {
        if (mData) {
            cudaFree(mData); // no throw from destructors; a failing free only leaks
            detail::deviceBytesNow().fetch_sub(mCapacity * sizeof(T));
        }
        mData = nullptr;
        mSize = mCapacity = 0;
    }
    void swap(DeviceBuffer& o) noexcept
    {
        std::swap(mData, o.mData);
        std::swap(mSize, o.mSize);
        std::swap(mCapacity, o.mCapacity);
        std::swap(mWhat, o.mWhat);
    }

    T* mData = nullptr;
    std::size_t mSize = 0, mCapacity = 0;
    const char* mWhat = "device buffer";
};

} // namespace splatwarp::cuda
