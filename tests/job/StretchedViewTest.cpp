#include <gtest/gtest.h>

#include <cmath>

#include "job/StretchedView.h"
#include "demo/DemoModels.h"
#include "field/RigidMotion.h"

using namespace splatwarp;

namespace {

/// Cells of 2^3 samples on a row along x, cell c at [c, c+1]^3 (rest = warped), each with its F
/// and one target opacity.
SampleSet rowOfCells(const std::vector<Mat3d>& gradients, const std::vector<float>& target)
{
    SampleSet s;
    s.samplesPerAxis = 2;
    s.cellSize = 1.0f;
    s.spacing = 0.5f;
    for (std::size_t c = 0; c < gradients.size(); ++c) {
        for (int k = 0; k < 8; ++k) {
            const float p[3] = {float(c) + 0.25f + 0.5f * float(k & 1), 0.25f + 0.5f * float((k >> 1) & 1),
                                0.25f + 0.5f * float(k >> 2)};
            for (int a = 0; a < 3; ++a) {
                s.restPositions.push_back(p[a]);
                s.warpedPositions.push_back(p[a] + 10.0f); // warped: moved by (10, 10, 10)
            }
            s.targetO.push_back(k == 3 ? target[c] : 0.0f);
            s.sampleCell.push_back(std::int32_t(c));
        }
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) s.cellGradient.push_back(float(gradients[c][r][k]));
        s.cellSkip.push_back(0);
    }
    return s;
}

Mat3d rotationZ(double angle)
{
    Mat3d r = Mat3d::identity();
    r[0][0] = r[1][1] = std::cos(angle);
    r[0][1] = -std::sin(angle);
    r[1][0] = std::sin(angle);
    return r;
}

Mat3d diagonal(double a, double b, double c)
{
    Mat3d d = Mat3d::identity();
    d[0][0] = a;
    d[1][1] = b;
    d[2][2] = c;
    return d;
}

/// Sum of one panel (column j, view row i) of a close-up sheet of size-pixel views (the sheet's
/// default padding 4; the label band is what is left above the two rows).
double panelSum(const Image& sheet, int j, int i, int size)
{
    const int pad = 4, band = sheet.height - 2 * (size + pad), left = pad + j * (size + pad), top = band + i * (size + pad);
    double sum = 0;
    for (int y = top; y < top + size; ++y)
        for (int x = left; x < left + size; ++x)
            for (int c = 0; c < 3; ++c) sum += sheet.pixels[sheet.index(x, y, c)];
    return sum;
}

} // namespace

TEST(StretchedView, PicksTheMostStretchedCellHoldingMatter)
{
    const Mat3d r = rotationZ(0.5);
    // cell 1 stretches most but holds no matter; cell 2 (1.3 along r's x axis) is the one.
    const SampleSet s = rowOfCells({Mat3d::identity(), diagonal(2.0, 1, 1), r * diagonal(1.3, 1, 0.8)}, {0.5f, 0.0f, 0.4f});
    const auto region = mostStretchedRegion(s, 0.1f);
    ASSERT_TRUE(region);
    EXPECT_EQ(region->cell, 2u);
    EXPECT_NEAR(region->stretch, 1.3, 1e-6);
    EXPECT_NEAR(std::abs(region->stretchAxis.x), std::cos(0.5), 1e-6); // the warped direction r * x
    EXPECT_NEAR(std::abs(region->stretchAxis.y), std::sin(0.5), 1e-6);
    EXPECT_NEAR(region->restCentre.x, 2.5, 1e-6);
    EXPECT_NEAR(region->warpedCentre.y, 10.5, 1e-6);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) EXPECT_NEAR(region->rotation[a][b], r[a][b], 1e-6);
    EXPECT_NEAR(region->radius, 1.5 * 1.3, 1e-6);
    EXPECT_FALSE(mostStretchedRegion(s, 0.6f)) << "no cell holds that much matter";
}

TEST(StretchedView, CloseUpShowsTheRestMovedRigidlyAndCropsTheRest)
{
    DemoModelOptions mo;
    mo.count = 400;
    const GaussianCloud rest = makeDemoModel("ring", mo);
    StretchedRegion region;
    region.restCentre = Vec3d(rest.means[0], rest.means[1], rest.means[2]);
    region.rotation = rotationZ(0.7);
    region.warpedCentre = region.restCentre + Vec3d(0.3, -0.2, 0.1);
    region.stretchAxis = Vec3d(0, 0, 1);
    region.radius = 0.3;
    const GaussianCloud moved =
        rigidlyMoved(rest, region.rotation, region.warpedCentre - region.rotation * region.restCentre);
    GaussianCloud withFarAway = moved; // a Gaussian outside the radius must not show
    withFarAway.append(moved, 0);
    for (int a = 0; a < 3; ++a) withFarAway.means[3 * (withFarAway.size() - 1) + std::size_t(a)] += 2.0f;
    GaussianCloud faded = moved; // Stage II differs
    for (float& v : faded.opacities) v -= 3.0f;
    const int size = 48;
    const Image sheet = renderStretchedCloseUp(rest, withFarAway, faded, region, size, RenderOptions{});
    for (int i = 0; i < 2; ++i) {
        const double restPanel = panelSum(sheet, 0, i, size), stage1 = panelSum(sheet, 1, i, size);
        EXPECT_GT(restPanel, 1.0) << "view " << i << " shows the region";
        EXPECT_DOUBLE_EQ(restPanel, stage1) << "view " << i << ": the rest lands where the region went";
        EXPECT_GT(std::abs(panelSum(sheet, 2, i, size) - stage1), 1.0) << "view " << i;
    }
}
