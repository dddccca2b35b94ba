#pragma once
/// @file ImageTestUtil.h
/// @brief Helpers shared by the image tests.
#include <random>

#include "image/Image.h"

namespace splatwarp::test {

/// @brief w x h image of uniform random values in [0, 1), deterministic per seed.
inline Image randomImage(int w, int h, int channels, unsigned seed)
{
    std::mt19937 gen(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Image img(w, h, channels);
    for (float& v : img.pixels) v = u(gen);
    return img;
}

} // namespace splatwarp::test
