#pragma once
/// @file SampleWarp.h
/// @brief Warp a sampled field with an embedded deformation (paper Sec. 3.2.1/3.2.3):
///        sample positions skinned, target SH rotated by the local rotation,
///        target opacity unchanged, and the per-cell deformation gradient F_k. Works on the flat
///        SampleSet only (no OpenVDB).
#include "deform/Deformation.h"
#include "deform/DeformationGraph.h"
#include "deform/NodeTransforms.h"
#include "field/SampleSet.h"

namespace splatwarp {


/// @brief Warp the samples from their rest positions with the deformation (graph, transforms).
/// @details warpedPositions = skinned restPositions (skin weights of the sample positions);
///          targetF of every sample rotated (ShRotation) by the polar rotation of its skinGradient;
///          targetO unchanged; cellGradient = computeCellGradients(). Call once on rest targets.
void warpSamples(SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms,
                 bool threaded = true);

/// @brief Check what warpSamples() needs: arrays of matching sizes, one transform per node.
/// @throws InputError naming the mismatch
void checkWarpSamples(const SampleSet& samples, const DeformationGraph& graph, const NodeTransforms& transforms);

/// @brief warpSamples() with a solved deformation (solveDeformation(), e.g. from a spec).
void warpSamples(SampleSet& samples, const Deformation& deformation, bool threaded = true);

/// @brief F_k for every cell: least-squares affine fit of the warped positions of the cell's 8
///        corner samples against their rest offsets from the corners' centroid,
///        F = (P Q^T)(Q Q^T)^-1 with P, Q the centred warped and rest corners (dimensionless).
void computeCellGradients(SampleSet& samples, bool threaded = true);

} // namespace splatwarp
