#pragma once
/// @file Adam.h
/// @brief Adam over a flat parameter array with one learning rate per parameter group.
#include <cmath>
#include <cstddef>
#include <vector>

namespace splatwarp {

/// @brief Adam moments for n parameters; fresh (zero) state on construction.
class Adam {
public:
    Adam(std::size_t n, float beta1, float beta2, float epsilon)
        : mM(n, 0.0f), mV(n, 0.0f), mBeta1(beta1), mBeta2(beta2), mEpsilon(epsilon)
    {
    }
    /// @brief Start step t (1-based): sets the bias corrections used by update().
    void beginStep(int t)
    {
        mCorr1 = 1.0 - std::pow(double(mBeta1), t);
        mCorr2 = 1.0 - std::pow(double(mBeta2), t);
    }
    /// @brief One update of parameter k with gradient g and learning rate lr.
    void update(std::size_t k, float& param, float g, float lr)
    {
        float& m = mM[k];
        float& v = mV[k];
        m = mBeta1 * m + (1.0f - mBeta1) * g;
        v = mBeta2 * v + (1.0f - mBeta2) * g * g;
        const double mHat = double(m) / mCorr1, vHat = double(v) / mCorr2;
        param -= float(double(lr) * mHat / (std::sqrt(vHat) + double(mEpsilon)));
    }

private:
    std::vector<float> mM, mV;
    float mBeta1, mBeta2, mEpsilon;
    double mCorr1 = 1.0, mCorr2 = 1.0;
};

} // namespace splatwarp
