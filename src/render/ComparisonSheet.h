#pragma once
/// @file ComparisonSheet.h
/// @brief A labelled grid of renders: one row per camera, one column per model (e.g. rest,
///        Stage I, Stage II), for `deform --render` and visual checks.
#include <string>
#include <vector>

#include "core/GaussianCloud.h"
#include "image/Image.h"
#include "render/Camera.h"
#include "render/Rasterizer.h"

namespace splatwarp {

/// @brief Options for renderComparisonSheet().
struct ComparisonSheetOptions {
    RenderOptions render;                    ///< how and where each cell is rendered (render/RenderDevice.h)
    int labelScale = 2;                      ///< image pixels per font pixel of the column labels
    int padding = 4;                         ///< pixels between cells and around labels
    Vec3f sheetColour{0.02f, 0.02f, 0.02f};  ///< RGB of the gaps and the label band
    Vec3f labelColour{1.0f, 1.0f, 1.0f};     ///< RGB of the label text
};

/// @brief Render every model from every camera into one RGBA image: a label band on top
///        (labels[j] centred over column j), then one row per camera. Cells are as large as the
///        largest camera; smaller renders sit at their cell's top-left corner.
/// @throws InputError when models and labels differ in count or either list is empty, or as
///         renderGaussiansOn().
Image renderComparisonSheet(const std::vector<const GaussianCloud*>& models, const std::vector<std::string>& labels,
                            const std::vector<Camera>& cameras, const ComparisonSheetOptions& options = {});

} // namespace splatwarp
