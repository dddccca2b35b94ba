#pragma once
/// @file CudaTestSupport.h
/// @brief Skip a GPU test cleanly, with a message, where no CUDA device is present.
#include <gtest/gtest.h>

#include "CudaBackends.h"

#define SPLATWARP_REQUIRE_GPU()                                                                         \
    if (!::splatwarp::cuda::cudaDeviceAvailable())                                                      \
    GTEST_SKIP() << "no CUDA GPU (cudaGetDeviceCount found none): GPU parity test compiled but not run"
