#pragma once
/// @file Progress.h
/// @brief Progress lines on stderr for long phases, and a millisecond stopwatch for reports.
#include <chrono>
#include <string>

namespace splatwarp {

/// @brief Monotonic stopwatch.
class Stopwatch {
public:
    Stopwatch() : mStart(std::chrono::steady_clock::now()) {}
    double ms() const
    {
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - mStart).count();
    }
    void reset() { mStart = std::chrono::steady_clock::now(); }

private:
    std::chrono::steady_clock::time_point mStart;
};

/// @brief Global switch for progress output (the CLI's --quiet turns it off; tests keep it off).
void setProgressEnabled(bool enabled);
bool progressEnabled();
/// @brief Print "splatwarp: <line>" to stderr when progress is enabled.
void progress(const std::string& line);

} // namespace splatwarp
