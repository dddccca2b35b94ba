#include "render/ComparisonSheet.h"

#include <algorithm>

#include "core/Error.h"
#include "image/BitmapFont.h"
#include "render/RenderDevice.h"

namespace splatwarp {

Image renderComparisonSheet(const std::vector<const GaussianCloud*>& models, const std::vector<std::string>& labels,
                            const std::vector<Camera>& cameras, const ComparisonSheetOptions& o)
{
    if (models.empty() || cameras.empty()) throw InputError("a comparison sheet needs at least one model and one camera");
    if (models.size() != labels.size())
        throw InputError(msg("comparison sheet: ", models.size(), " models but ", labels.size(), " labels"));
    int cellW = 0, cellH = 0;
    for (const Camera& c : cameras) {
        cellW = std::max(cellW, c.width);
        cellH = std::max(cellH, c.height);
    }
    const int cols = int(models.size()), rows = int(cameras.size());
    const int bandH = kGlyphHeight * o.labelScale + 2 * o.padding;
    const int width = cols * cellW + (cols + 1) * o.padding;
    const int height = bandH + rows * cellH + rows * o.padding;
    Image sheet(width, height, 4, 1.0f);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c) sheet.at(x, y, c) = o.sheetColour[c];

    for (int j = 0; j < cols; ++j) {
        const int left = o.padding + j * (cellW + o.padding);
        // Labels wider than the cell are cut at the cell edge rather than overlapping the next one.
        std::string label = labels[std::size_t(j)];
        while (!label.empty() && textWidth(label, o.labelScale) > cellW) label.pop_back();
        drawText(sheet, left + (cellW - textWidth(label, o.labelScale)) / 2, o.padding, label, o.labelScale,
                 o.labelColour);
        if (models[std::size_t(j)] == nullptr) throw InputError(msg("comparison sheet: model '", labels[std::size_t(j)], "' is missing"));
        for (int i = 0; i < rows; ++i) {
            const Image cell = renderGaussiansOn(*models[std::size_t(j)], cameras[std::size_t(i)], o.render);
            const int top = bandH + i * (cellH + o.padding);
            for (int y = 0; y < cell.height; ++y)
                for (int x = 0; x < cell.width; ++x)
                    for (int c = 0; c < 4; ++c) sheet.at(left + x, top + y, c) = cell.at(x, y, c);
        }
    }
    return sheet;
}

} // namespace splatwarp
