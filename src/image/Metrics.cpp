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

/// Separable 'valid' filtering of one plane (w x h) with a normalised 1D window.
std::vector<double> filterValid(const std::vector<double>& plane, int w, int h, const std::vector<double>& k)
{
    const int n = int(k.size()), ow = w - n + 1, oh = h - n + 1;
    std::vector<double> rows(std::size_t(w) * oh, 0.0), out(std::size_t(ow) * oh, 0.0);
    for (int y = 0; y < oh; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0;
            for (int i = 0; i < n; ++i) s += k[i] * plane[std::size_t(y + i) * w + x];
            rows[std::size_t(y) * w + x] = s;
        }
    for (int y = 0; y < oh; ++y)
        for (int x = 0; x < ow; ++x) {
            double s = 0;
            for (int i = 0; i < n; ++i) s += k[i] * rows[std::size_t(y) * w + x + i];
            out[std::size_t(y) * ow + x] = s;
        }
    return out;
}

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
    const int w = a.width, h = a.height;
    const std::size_t n = std::size_t(w) * h;
    double total = 0;
    for (int c = 0; c < channels; ++c) {
        std::vector<double> pa(n), pb(n), paa(n), pbb(n), pab(n);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const std::size_t i = std::size_t(y) * w + x;
                pa[i] = a.at(x, y, c);
                pb[i] = b.at(x, y, c);
                paa[i] = pa[i] * pa[i];
                pbb[i] = pb[i] * pb[i];
                pab[i] = pa[i] * pb[i];
            }
        const auto ma = filterValid(pa, w, h, window), mb = filterValid(pb, w, h, window);
        const auto saa = filterValid(paa, w, h, window), sbb = filterValid(pbb, w, h, window),
                   sab = filterValid(pab, w, h, window);
        double sum = 0;
        for (std::size_t i = 0; i < ma.size(); ++i) {
            const double va = saa[i] - ma[i] * ma[i], vb = sbb[i] - mb[i] * mb[i], cov = sab[i] - ma[i] * mb[i];
            sum += ((2 * ma[i] * mb[i] + c1) * (2 * cov + c2)) /
                   ((ma[i] * ma[i] + mb[i] * mb[i] + c1) * (va + vb + c2));
        }
        total += sum / double(ma.size());
    }
    return total / channels;
}

} // namespace splatwarp
