#include "image/Metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/Error.h"

namespace splatwarp {

namespace {

/// Colour channels both images share; throws when they cannot be compared.
int compareChannels(const Image& a, const Image& b)
{
    if (a.width != b.width || a.height != b.height)
        throw InputError(msg("images differ in size: ", a.width, "x", a.height, " vs ", b.width, "x", b.height));
    if (a.empty() || b.empty()) throw InputError("cannot compare empty images");
    return std::min(3, std::min(a.channels, b.channels));
}

/// One colour channel's local statistics for SSIM, an output row at a time: the window's
/// vertical pass over its rows of a and b, then its horizontal pass. A row holds 5 x width doubles,
/// where the whole planes took 10 x width x height (23 GB at 16384^2); each value is summed in the
/// same order as by whole planes, so the result is the same to the bit.
class SsimRows {
public:
    SsimRows(const Image& a, const Image& b, int channel, const std::vector<double>& window)
        : mA(a), mB(b), mC(channel), mK(window), mV(5 * std::size_t(a.width))
    {
    }

    /// Adds the SSIM map over output row y (window rows y ... y + window - 1) to `sum`, one
    /// value at a time as the whole-plane sum did.
    void addRow(int y, double c1, double c2, double& sum)
    {
        verticalPass(y);
        const int w = mA.width, n = int(mK.size());
        for (int x = 0; x + n <= w; ++x) {
            double m[5] = {0, 0, 0, 0, 0}; // means of a, b, a^2, b^2, ab
            for (int q = 0; q < 5; ++q)
                for (int i = 0; i < n; ++i) m[q] += mK[std::size_t(i)] * mV[std::size_t(q) * w + std::size_t(x + i)];
            // E[a^2] - E[a]^2 cancels: with display values near 1e35 it came out far below 0 and SSIM
            // at -3.9e16. A variance is not negative, nor a covariance beyond both (SSIM in [-1, 1]).
            const double va = std::max(0.0, m[2] - m[0] * m[0]), vb = std::max(0.0, m[3] - m[1] * m[1]);
            const double bound = std::sqrt(va * vb), cov = std::clamp(m[4] - m[0] * m[1], -bound, bound);
            sum += ((2 * m[0] * m[1] + c1) * (2 * cov + c2)) / ((m[0] * m[0] + m[1] * m[1] + c1) * (va + vb + c2));
        }
    }

private:
    void verticalPass(int y)
    {
        const int w = mA.width, n = int(mK.size());
        for (int x = 0; x < w; ++x) {
            double v[5] = {0, 0, 0, 0, 0};
            for (int i = 0; i < n; ++i) {
                const double pa = mA.at(x, y + i, mC), pb = mB.at(x, y + i, mC), k = mK[std::size_t(i)];
                v[0] += k * pa;
                v[1] += k * pb;
                v[2] += k * (pa * pa);
                v[3] += k * (pb * pb);
                v[4] += k * (pa * pb);
            }
            for (int q = 0; q < 5; ++q) mV[std::size_t(q) * w + std::size_t(x)] = v[q];
        }
    }

    const Image& mA;
    const Image& mB;
    int mC;
    const std::vector<double>& mK;
    std::vector<double> mV; ///< the vertical pass of a, b, a^2, b^2, ab: 5 rows of width
};

} // namespace

double psnr(const Image& a, const Image& b, double peak)
{
    const int channels = compareChannels(a, b);
    double sum = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x)
            for (int c = 0; c < channels; ++c) {
                const double d = double(a.at(x, y, c)) - double(b.at(x, y, c));
                sum += d * d;
            }
    const double mse = sum / (double(a.width) * a.height * channels);
    if (mse == 0.0) return std::numeric_limits<double>::infinity();
    return 10.0 * std::log10(peak * peak / mse);
}

double ssim(const Image& a, const Image& b, const SsimOptions& o)
{
    const int channels = compareChannels(a, b);
    if (o.window < 1 || o.window % 2 == 0) throw InputError(msg("SSIM window must be odd and positive, got ", o.window));
    if (a.width < o.window || a.height < o.window)
        throw InputError(msg("SSIM needs images of at least ", o.window, "x", o.window, " pixels, got ", a.width, "x",
                             a.height));
    std::vector<double> window(std::size_t(o.window));
    double norm = 0;
    for (int i = 0; i < o.window; ++i) {
        const double d = i - (o.window - 1) / 2;
        window[std::size_t(i)] = std::exp(-d * d / (2.0 * o.sigma * o.sigma));
        norm += window[std::size_t(i)];
    }
    for (double& k : window) k /= norm;
    const double c1 = (o.k1 * o.dynamicRange) * (o.k1 * o.dynamicRange);
    const double c2 = (o.k2 * o.dynamicRange) * (o.k2 * o.dynamicRange);
    const int rows = a.height - o.window + 1, columns = a.width - o.window + 1;
    double total = 0;
    for (int c = 0; c < channels; ++c) {
        SsimRows stats(a, b, c, window);
        double sum = 0;
        for (int y = 0; y < rows; ++y) stats.addRow(y, c1, c2, sum);
        total += sum / (double(rows) * double(columns));
    }
    return total / channels;
}

} // namespace splatwarp
