#pragma once
/// @file GaussianCloud.h
/// @brief A 3D Gaussian Splatting model as a structure of arrays, with raw (pre-activation)
///        parameters exactly as 3DGS stores them.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/HostDevice.h"
#include "core/SmallMath.h"

namespace splatwarp {

/// @brief Number of SH coefficients per colour channel for a degree: (d+1)^2.
SPLATWARP_HOST_DEVICE int shCoeffCount(int degree) { return (degree + 1) * (degree + 1); }

/// @brief Remove the rows i with drop[i] != 0 from an array of `stride` values per row, keeping the
///        others in order (a per-Gaussian array kept in step with GaussianCloud::erase()).
template <class T>
void eraseRows(std::vector<T>& rows, const std::vector<std::uint8_t>& drop, std::size_t stride = 1)
{
    std::size_t to = 0;
    for (std::size_t i = 0; i < drop.size(); ++i) {
        if (drop[i]) continue;
        if (to != i)
            for (std::size_t k = 0; k < stride; ++k) rows[to * stride + k] = rows[i * stride + k];
        ++to;
    }
    rows.resize(to * stride);
}

/// @brief 3DGS model, structure of arrays. N = size().
/// @note  Activations as in 3DGS: scale = exp(logScale), opacity = sigmoid(logitOpacity),
///        the quaternion is normalised on use (never silently rewritten on load).
struct GaussianCloud {
    int shDegree = 0;                ///< 0..3
    std::vector<float> means;        ///< [N,3] centres
    std::vector<float> rotations;    ///< [N,4] quaternion w,x,y,z (raw, possibly unnormalised)
    std::vector<float> logScales;    ///< [N,3] log of the per-axis standard deviation
    std::vector<float> opacities;    ///< [N]   logit of alpha
    std::vector<float> sh;           ///< [N,K,3] K = (shDegree+1)^2; coefficient 0 is f_dc; RGB interleaved

    std::size_t size() const { return opacities.size(); }
    bool empty() const { return opacities.empty(); }
    int shCoeffs() const { return shCoeffCount(shDegree); }
    /// @brief Floats of SH per Gaussian: K*3.
    int shStride() const { return shCoeffs() * 3; }

    /// @brief Resize every array for n Gaussians of the given SH degree (new entries zero,
    ///        rotations identity).
    void resize(std::size_t n, int degree);
    /// @brief Append Gaussian i of another cloud of the same SH degree.
    void append(const GaussianCloud& other, std::size_t i);
    /// @brief Overwrite Gaussian i with Gaussian j of another cloud of the same SH degree.
    void assign(std::size_t i, const GaussianCloud& other, std::size_t j);
    /// @brief Remove every Gaussian i with drop[i] != 0 (drop: [N]), keeping the others in order.
    void erase(const std::vector<std::uint8_t>& drop);
    /// @brief Whether Gaussian i holds exactly (bit for bit) the values of Gaussian j of another cloud.
    bool sameGaussian(std::size_t i, const GaussianCloud& other, std::size_t j) const;
    /// @brief Throws InputError if array sizes disagree or the degree is outside 0..3.
    void checkConsistent() const;

    Vec3f mean(std::size_t i) const { return {means[3 * i], means[3 * i + 1], means[3 * i + 2]}; }
    void setMean(std::size_t i, const Vec3f& p) { means[3 * i] = p.x; means[3 * i + 1] = p.y; means[3 * i + 2] = p.z; }
    Quatf rotation(std::size_t i) const
    {
        return {rotations[4 * i], rotations[4 * i + 1], rotations[4 * i + 2], rotations[4 * i + 3]};
    }
    void setRotation(std::size_t i, const Quatf& q)
    {
        rotations[4 * i] = q.w; rotations[4 * i + 1] = q.x; rotations[4 * i + 2] = q.y; rotations[4 * i + 3] = q.z;
    }
    /// @brief Activated scale (standard deviations) exp(logScale).
    Vec3f scale(std::size_t i) const;
    /// @brief Activated opacity sigmoid(logit).
    float alpha(std::size_t i) const { return sigmoid(opacities[i]); }
    /// @brief alpha s0 s1 s2 in double: the field's mass up to (2 pi)^1.5 (heaviest-first orders, merges).
    double mass(std::size_t i) const
    {
        const Vec3f s = scale(i);
        return double(alpha(i)) * double(s.x) * double(s.y) * double(s.z);
    }
    float* shOf(std::size_t i) { return sh.data() + i * std::size_t(shStride()); }
    const float* shOf(std::size_t i) const { return sh.data() + i * std::size_t(shStride()); }
};

/// @brief The opacity logit of w x alpha for alpha = sigmoid(logit), w in (0, 1] (a dimmer copy: split
///        children), in double; where w alpha underflows, logit + log w (its limit).
float scaledOpacityLogit(float logit, double w);

/// @brief Axis-aligned bounding box of the centres (min, max). Empty cloud gives zeros.
void centreBounds(const GaussianCloud& g, Vec3f& lo, Vec3f& hi);

/// @brief A copy with another SH degree: higher bands dropped, or new bands zero (benchmarks,
///        writers of degree-limited formats).
GaussianCloud withShDegree(const GaussianCloud& g, int degree);

} // namespace splatwarp
