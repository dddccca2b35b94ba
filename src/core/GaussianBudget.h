#pragma once
/// @file GaussianBudget.h
/// @brief The most Gaussians an output may hold (`--max-gaussians N|X×`): an absolute count or a
///        factor of the input's count. Every step that adds Gaussians spends from what is left.
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <string>

#include "core/Error.h"

namespace splatwarp {

struct GaussianBudget {
    double factor = 0;     ///< X of "X×": the limit is floor(X * input); 0 when count is used
    std::size_t count = 0; ///< N: the limit itself; 0 when factor is used

    /// @brief The most Gaussians the output of a model of `input` Gaussians may hold.
    /// @throws UsageError when that is below the input (no step removes Gaussians to meet a budget).
    std::size_t limit(std::size_t input) const
    {
        const double wanted = count > 0 ? double(count) : std::floor(factor * double(input) + 1e-9);
        if (wanted < double(input))
            throw UsageError("--max-gaussians " + text() + " is below the input's " + std::to_string(input) +
                             " Gaussians; no step removes Gaussians to meet it (1x: no growth)");
        return wanted >= double(std::numeric_limits<std::size_t>::max()) ? std::numeric_limits<std::size_t>::max()
                                                                          : std::size_t(wanted);
    }

    /// @brief Gaussians the steps may add to a model of `input` Gaussians.
    std::size_t added(std::size_t input) const { return limit(input) - input; }

    /// @brief As the user wrote it, normalised: "250000" or "1.5x".
    std::string text() const
    {
        if (count > 0) return std::to_string(count);
        std::string f = std::to_string(factor);
        f.erase(f.find_last_not_of('0') + 1);
        if (!f.empty() && f.back() == '.') f.pop_back();
        return f + "x";
    }
};

/// @brief "N" (a whole count >= 1) or "X×" / "Xx" (a factor >= 1, at most 1000); "" when the text is
///        neither, else the reason it is refused.
/// @param out receives the budget when the text is valid
inline std::string parseGaussianBudget(const std::string& text, GaussianBudget& out)
{
    std::string s = text;
    bool isFactor = false;
    for (const std::string& times : {std::string("\u00d7"), std::string("x"), std::string("X")})
        if (s.size() > times.size() && s.compare(s.size() - times.size(), times.size(), times) == 0) {
            s.erase(s.size() - times.size());
            isFactor = true;
            break;
        }
    if (s.empty() || s.find_first_not_of("0123456789.") != std::string::npos || (!isFactor && s.find('.') != std::string::npos))
        return "expected a whole count N or a factor such as 1.5x, got '" + text + "'";
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (end != s.c_str() + s.size() || !std::isfinite(v)) return "expected a number, got '" + text + "'";
    if (isFactor) {
        if (v < 1.0 || v > 1000.0) return "a factor must be from 1x (no growth) to 1000x, got '" + text + "'";
        out = {v, 0};
    } else {
        if (v < 1.0 || v > 1e12) return "a count must be from 1 to 1e12, got '" + text + "'";
        out = {0, std::size_t(v)};
    }
    return "";
}

} // namespace splatwarp
