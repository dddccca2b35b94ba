#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "image/Metrics.h"
#include "render/Rasterizer.h"
#include "train/ImageLoss.h"
#include "train/Trainer.h"

namespace splatwarp {
namespace {

Image randomPicture(int w, int h, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(0.1f, 0.9f);
    Image img(w, h, 3);
    for (float& v : img.pixels) v = u(rng);
    return img;
}

// The D-SSIM + L1 gradient against central differences (double loss, float gradient).
TEST(ImageLossTest, GradientMatchesFiniteDifferences)
{
    const Image y = randomPicture(14, 11, 1);
    Image x = randomPicture(14, 11, 2);
    const ImageLossResult r = imageLoss(x, y, 0.2, false);
    EXPECT_NEAR(r.loss, 0.8 * r.l1 + 0.2 * (1 - r.ssim), 1e-12);
    double worst = 0, largest = 0;
    for (std::size_t i = 0; i < x.pixels.size(); i += 7) {
        const float keep = x.pixels[i];
        const float h = 1e-3f;
        x.pixels[i] = keep + h;
        const double lp = imageLoss(x, y, 0.2, false).loss;
        x.pixels[i] = keep - h;
        const double lm = imageLoss(x, y, 0.2, false).loss;
        x.pixels[i] = keep;
        const double fd = (lp - lm) / (2.0 * double(h));
        worst = std::max(worst, std::abs(fd - r.gradient[i]));
        largest = std::max(largest, std::abs(fd));
    }
    EXPECT_LT(worst, 1e-3 * largest); // measured 1.2e-5 relative: the float step of x
    const ImageLossResult same = imageLoss(y, y);
    EXPECT_NEAR(same.loss, 0.0, 1e-12);
    EXPECT_NEAR(same.ssim, 1.0, 1e-12);
}

/// Three coloured Gaussians seen by two cameras.
GaussianCloud truthScene()
{
    GaussianCloud g;
    g.resize(3, 0);
    const float pos[3][3] = {{-0.4f, 0.0f, 0.0f}, {0.3f, -0.2f, 0.1f}, {0.1f, 0.35f, -0.2f}};
    const float rgb[3][3] = {{0.9f, 0.2f, 0.1f}, {0.1f, 0.8f, 0.3f}, {0.2f, 0.3f, 0.9f}};
    for (std::size_t i = 0; i < 3; ++i) {
        g.setMean(i, Vec3f(pos[i][0], pos[i][1], pos[i][2]));
        for (int a = 0; a < 3; ++a) g.logScales[3 * i + std::size_t(a)] = std::log(0.12f + 0.04f * float(a));
        g.opacities[i] = 1.5f;
        for (int c = 0; c < 3; ++c) g.sh[3 * i + std::size_t(c)] = float((rgb[i][c] - 0.5) / 0.28209479177387814);
    }
    return g;
}

// Training a perturbed copy on two rendered views brings it back (no densification).
TEST(TrainerTest, TinySceneConverges)
{
    const GaussianCloud truth = truthScene();
    std::vector<TrainingView> views;
    for (double az : {0.0, 1.2}) {
        const Vec3d eye(3.0 * std::sin(az), -0.5, -3.0 * std::cos(az));
        TrainingView v;
        v.camera = Camera::lookAt(eye, Vec3d(0, 0, 0), Vec3d(0, -1, 0), 40.0, 48, 40);
        v.image = renderGaussians(truth, v.camera);
        v.image.channels = 4;
        views.push_back(v);
    }
    GaussianCloud init = truth;
    for (std::size_t i = 0; i < init.size(); ++i) {
        init.means[3 * i] += 0.08f;
        init.means[3 * i + 1] -= 0.05f;
        for (int c = 0; c < 3; ++c) init.sh[3 * i + std::size_t(c)] = 0.0f; // grey
        init.opacities[i] = 0.0f;
    }
    TrainOptions o = compressedSchedule(600);
    o.shDegree = 0;
    o.densifyFrom = o.densifyUntil = o.opacityResetInterval = 1 << 30; // no densification or reset
    o.positionLrStart = 2e-3;                 // a tiny scene: larger steps than a real capture needs
    o.progressEvery = 0;
    const double before = scoreViews(init, views, o.background).meanPsnr;
    TrainReport report;
    const GaussianCloud out = trainGaussians(init, views, o, &report);
    const ViewScores after = scoreViews(out, views, o.background);
    EXPECT_LT(before, 26.0); // mostly black background: grey, shifted splats still score 25 dB
    EXPECT_GT(after.meanPsnr, 35.0) << "from " << before;
    std::printf("tiny scene: %.2f -> %.2f dB, SSIM %.4f\n", before, after.meanPsnr, after.meanSsim);
    EXPECT_GT(after.meanSsim, 0.98);
    EXPECT_EQ(report.gaussians, 3u);
    EXPECT_LT(report.finalLoss, 0.01);
}

TEST(TrainerTest, ScheduleIsThe30kOneScaled)
{
    const TrainOptions o = compressedSchedule(3000);
    EXPECT_EQ(o.densifyUntil, 1500);
    EXPECT_EQ(o.densifyInterval, 25); // 10 scaled, but at least 25
    EXPECT_EQ(o.opacityResetInterval, 300);
    EXPECT_EQ(o.shInterval, 100);
    EXPECT_DOUBLE_EQ(o.featureLr, TrainOptions().featureLr);
}

} // namespace
} // namespace splatwarp
