# All dependencies come from Debian packages (scripts/setup.sh installs them).
find_package(Threads REQUIRED)
find_package(TBB REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(nlohmann_json 3 REQUIRED)
find_package(PNG REQUIRED)
find_package(ZLIB REQUIRED)  # .spz (gzip)
find_package(zstd REQUIRED CONFIG)  # .spz version 4 (one zstd stream per attribute; Debian libzstd-dev)
find_package(OpenEXR REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(WEBP REQUIRED IMPORTED_TARGET libwebp)  # SOG: lossless WebP images (Debian libwebp-dev)
find_package(assimp REQUIRED)  # meshes for image ground truth (OBJ, PLY, glTF, OFF ...)
find_package(JPEG REQUIRED)    # JPEG textures of those meshes
find_path(CLI11_INCLUDE_DIR CLI/CLI.hpp REQUIRED)
find_path(NANOFLANN_INCLUDE_DIR nanoflann.hpp REQUIRED)

# Debian ships OpenVDB's FindOpenVDB.cmake under its cmake dir rather than a config package.
list(APPEND CMAKE_MODULE_PATH "/usr/lib/x86_64-linux-gnu/cmake/OpenVDB" "/usr/lib/cmake/OpenVDB")
find_package(OpenVDB REQUIRED)
find_path(NANOVDB_INCLUDE_DIR nanovdb/NanoVDB.h REQUIRED)
