#pragma once
/// @file HostDevice.h
/// @brief One macro for functions shared by the CPU path and the CUDA kernels (one source of truth).
#if defined(__CUDACC__)
#define SPLATWARP_HOST_DEVICE __host__ __device__ __forceinline__
#else
#define SPLATWARP_HOST_DEVICE inline
#endif
