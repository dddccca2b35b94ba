#include "core/RunControl.h"

namespace splatwarp {

namespace {
// The loop that reports runs on the thread that installed the control (TBB workers never report).
thread_local const RunControl* tControl = nullptr;
} // namespace

RunControlScope::RunControlScope(const RunControl& control) : mPrevious(tControl) { tControl = &control; }

RunControlScope::~RunControlScope() { tControl = mPrevious; }

void checkCancelled()
{
    if (tControl && tControl->cancel && tControl->cancel->load()) throw Cancelled();
}

void reportProgress(const char* phase, int done, int total)
{
    if (!tControl) return;
    checkCancelled();
    if (tControl->onProgress) tControl->onProgress(phase, done, total);
    checkCancelled();
}

} // namespace splatwarp
