#pragma once
/// @file SampleWarp.h
/// @brief Forwarding header: sample warping moved to the core library (deform/SampleWarp.h; it
///        uses no OpenVDB) so the CUDA kernels can register a GPU version.
#include "deform/SampleWarp.h"
