#pragma once
/// @file RunControl.h
/// @brief Progress and cancel for a long run driven from elsewhere (the editor's Refine button, a
///        library caller): the thread that runs the work installs a RunControl; the Stage II loop
///        and the steps between report each iteration, and a cancel stops the run at the next
///        report (within one iteration) by throwing Cancelled.
#include <atomic>
#include <functional>
#include <string>

#include "core/Error.h"

namespace splatwarp {

/// @brief The run was cancelled (RunControl::cancel was set); nothing of it should be written.
class Cancelled : public Error {
public:
    Cancelled() : Error("cancelled") {}
};

/// @brief What a driver of a run sees and sets.
struct RunControl {
    /// Called from the running thread: the phase ("Stage II"), iterations done and planned.
    std::function<void(const std::string& phase, int done, int total)> onProgress;
    /// Set (from any thread) to stop the run at its next progress report.
    const std::atomic<bool>* cancel = nullptr;
};

/// @brief Installs a RunControl for the work this thread runs while the scope lives.
class RunControlScope {
public:
    explicit RunControlScope(const RunControl& control);
    ~RunControlScope();
    RunControlScope(const RunControlScope&) = delete;
    RunControlScope& operator=(const RunControlScope&) = delete;

private:
    const RunControl* mPrevious;
};

/// @brief Tell this thread's RunControl (if any) how far a phase is; throws Cancelled when its
///        cancel flag is set. A no-op without a RunControl (the CLI).
void reportProgress(const char* phase, int done, int total);

/// @brief Throws Cancelled when this thread's RunControl has been cancelled (between steps).
void checkCancelled();

/// @brief The steps of a run that are not iterations (the refine's warp, splits, keep), each
///        reported as a phase when it starts: done = the steps started before it, of `total`. A
///        driver sees the run move before the first iteration, and a cancel stops it there.
class StepProgress {
public:
    explicit StepProgress(int total) : mTotal(total) {}
    void start(const char* name) { reportProgress(name, mDone++, mTotal); }

private:
    int mDone = 0, mTotal;
};

} // namespace splatwarp
