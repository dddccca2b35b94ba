#include "train/ImageLoss.h"

#include <cmath>

#include "core/Error.h"
#include "core/ParallelFor.h"

namespace splatwarp {

namespace {

constexpr int kRadius = 5;         // 11-tap window (3DGS)
constexpr double kSigma = 1.5;     // its standard deviation
constexpr double kC1 = 0.01 * 0.01; // (K1 L)^2 with L = 1
constexpr double kC2 = 0.03 * 0.03; // (K2 L)^2

struct Window {
    double w[2 * kRadius + 1];
    Window()
    {
        double sum = 0;
        for (int k = -kRadius; k <= kRadius; ++k) sum += w[k + kRadius] = std::exp(-0.5 * k * k / (kSigma * kSigma));
        for (double& v : w) v /= sum;
    }
};

/// Separable zero-padded "same" filtering of a W x H plane (its own adjoint: the window is symmetric).
std::vector<double> blur(const std::vector<double>& in, int width, int height, bool threaded)
{
    static const Window g;
    std::vector<double> tmp(in.size()), out(in.size());
    parallelFor(std::size_t(height), 8, threaded, [&](std::size_t y) {
        for (int x = 0; x < width; ++x) {
            double s = 0;
            for (int k = -kRadius; k <= kRadius; ++k)
                if (x + k >= 0 && x + k < width) s += g.w[k + kRadius] * in[y * std::size_t(width) + std::size_t(x + k)];
            tmp[y * std::size_t(width) + std::size_t(x)] = s;
        }
    });
    parallelFor(std::size_t(height), 8, threaded, [&](std::size_t y) {
        for (int x = 0; x < width; ++x) {
            double s = 0;
            for (int k = -kRadius; k <= kRadius; ++k) {
                const long yy = long(y) + k;
                if (yy >= 0 && yy < height) s += g.w[k + kRadius] * tmp[std::size_t(yy) * std::size_t(width) + std::size_t(x)];
            }
            out[y * std::size_t(width) + std::size_t(x)] = s;
        }
    });
    return out;
}

/// Mean SSIM of one channel and its gradient w.r.t. x (added into grad, scaled by `scale`).
double ssimChannel(const std::vector<double>& x, const std::vector<double>& y, int w, int h, double scale,
                   std::vector<double>& grad, bool threaded)
{
    const std::size_t n = x.size();
    std::vector<double> xx(n), yy(n), xy(n);
    for (std::size_t i = 0; i < n; ++i) {
        xx[i] = x[i] * x[i];
        yy[i] = y[i] * y[i];
        xy[i] = x[i] * y[i];
    }
    const std::vector<double> mx = blur(x, w, h, threaded), my = blur(y, w, h, threaded);
    const std::vector<double> exx = blur(xx, w, h, threaded), eyy = blur(yy, w, h, threaded), exy = blur(xy, w, h, threaded);
    std::vector<double> dM(n), dE2(n), dE12(n);
    double sum = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const double sxx = exx[i] - mx[i] * mx[i], syy = eyy[i] - my[i] * my[i], sxy = exy[i] - mx[i] * my[i];
        const double a1 = 2 * mx[i] * my[i] + kC1, a2 = 2 * sxy + kC2;
        const double b1 = mx[i] * mx[i] + my[i] * my[i] + kC1, b2 = sxx + syy + kC2;
        const double s = a1 * a2 / (b1 * b2);
        sum += s;
        const double dMu = 2 * my[i] * a2 / (b1 * b2) - s * 2 * mx[i] / b1;
        const double dSxy = 2 * a1 / (b1 * b2), dSxx = -s / b2;
        // sxx = E[x^2] - mx^2, sxy = E[xy] - mx my: back to the three filtered maps.
        dM[i] = dMu - 2 * mx[i] * dSxx - my[i] * dSxy;
        dE2[i] = dSxx;
        dE12[i] = dSxy;
    }
    const std::vector<double> gM = blur(dM, w, h, threaded), gE2 = blur(dE2, w, h, threaded), gE12 = blur(dE12, w, h, threaded);
    for (std::size_t i = 0; i < n; ++i) grad[i] += scale * (gM[i] + 2 * x[i] * gE2[i] + y[i] * gE12[i]);
    return sum / double(n);
}

} // namespace

ImageLossResult imageLoss(const Image& render, const Image& target, double lambda, bool threaded)
{
    if (render.width != target.width || render.height != target.height || render.channels < 3 || target.channels < 3)
        throw InputError(msg("image loss: a ", render.width, "x", render.height, " render against a ", target.width, "x",
                             target.height, " picture"));
    const int w = render.width, h = render.height;
    const std::size_t n = std::size_t(w) * std::size_t(h);
    ImageLossResult r;
    r.gradient.assign(3 * n, 0.0f);
    const double count = 3.0 * double(n);
    for (int c = 0; c < 3; ++c) {
        std::vector<double> x(n), y(n), g(n, 0.0);
        for (std::size_t i = 0; i < n; ++i) {
            x[i] = render.pixels[i * std::size_t(render.channels) + std::size_t(c)];
            y[i] = target.pixels[i * std::size_t(target.channels) + std::size_t(c)];
        }
        // d(1 - SSIM)/dx, SSIM averaged over the three channels.
        r.ssim += ssimChannel(x, y, w, h, -lambda / count, g, threaded) / 3.0;
        for (std::size_t i = 0; i < n; ++i) {
            const double d = x[i] - y[i];
            r.l1 += std::abs(d) / count;
            g[i] += (1 - lambda) * (d > 0 ? 1.0 : (d < 0 ? -1.0 : 0.0)) / count;
            r.gradient[3 * i + std::size_t(c)] = float(g[i]);
        }
    }
    r.loss = (1 - lambda) * r.l1 + lambda * (1 - r.ssim);
    return r;
}

} // namespace splatwarp
