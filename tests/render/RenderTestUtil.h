#pragma once
/// @file RenderTestUtil.h
/// @brief Helpers shared by the render tests: small sample models and orbit cameras.
#include <vector>

#include "render/Camera.h"
#include "demo/DemoModels.h"

namespace splatwarp::test {

/// @brief A sample model (stripes, ring) with fewer Gaussians, for fast tests.
inline GaussianCloud smallSample(const char* name, std::size_t count)
{
    DemoModelOptions o;
    o.count = count;
    return makeDemoModel(name, o);
}

/// @brief `views` orbit cameras of width x height around a model (other options default).
inline std::vector<Camera> smallOrbit(const GaussianCloud& g, int views, int width, int height,
                                      double elevationDeg = OrbitOptions{}.elevationDeg)
{
    OrbitOptions o;
    o.views = views;
    o.width = width;
    o.height = height;
    o.elevationDeg = elevationDeg;
    return orbitCameras(g, o);
}

} // namespace splatwarp::test
